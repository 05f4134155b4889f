"""A long unattended capture without waiting for it: the simulator writes four hours of two TDS-V8 drives
that trip every 10-30 minutes (faster than real time), and `replay --trigger ... --ring` runs the same
session a live capture runs over it.  Every window holds its trigger frames and every frame of the
capture over its pre/post span, and the replay's memory stays flat (its RSS sampled from /proc while it
runs: no growth from the first half of the capture to the end)."""

import subprocess
import sys
import time

import pytest

from sniffer.capture.session import decode_capture
from sniffer.formats.mcap.reader import read_frames
from sniffer.triggers import read_trigger
from helpers import frames_of, window_holds

SNIFFER = [sys.executable, "-m", "sniffer"]
HOURS = 4
# Each test is minutes of CPU (four simulated hours, simulated and replayed); on a loaded machine the wall time
# stretches several-fold (2 cores, a load of 13: the first test took over pytest's 300 s default, with the
# day's simulation).  What the tests check does not depend on time; the bounds only catch a hang.
LOADED_S = 3600
pytestmark = pytest.mark.timeout(LOADED_S)


def _rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    path = tmp_path_factory.mktemp("day") / "day.mcap"
    r = subprocess.run(SNIFFER + ["simulate", "--scenario", "tds-v8", "--duration", str(HOURS * 3600), "--seed", "5",
                                  "--param", "poll_period_ms=1000", "--param", "unit1.trip_every_s=(600.0, 1800.0)",
                                  "--param", "unit2.trip_every_s=(900.0, 1800.0)", "--out", str(path)],
                       capture_output=True, text=True, timeout=LOADED_S)
    assert r.returncode == 0, r.stderr
    return path


@pytest.fixture(scope="module")
def day_frames(day):
    """(t in s from the capture's start, raw hex, a fault?) of every frame of the day, read from its /frames
    records (what `simulate` decoded as it wrote them): the reference both tests hold the replays against,
    read once instead of decoding the four hours again."""
    return [(round(r["t"], 9), r["raw"], any(a["code"] == "model.fault" for a in r["annotations"]))
            for r in read_frames(str(day))]


def test_a_simulated_day_keeps_every_window_whole_with_flat_memory(day, day_frames, tmp_path):
    windows = tmp_path / "windows"
    windows.mkdir()
    proc = subprocess.Popen(SNIFFER + ["replay", str(day), "--quiet", "--ring", "--windows", str(windows),
                                       "--trigger", "fault", "--trigger", "rate(fault) >= 2/5s",
                                       "--pre", "5m", "--post", "1m"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    samples = []
    while proc.poll() is None:
        kb = _rss_kb(proc.pid)
        if kb:
            samples.append(kb)
        time.sleep(0.05)
    out, err = proc.communicate()
    assert proc.returncode == 0, err
    # memory: what the second half of the run peaks at is what the run held once it was going
    assert len(samples) >= 20, samples
    quarter = len(samples) // 4
    settled, late = max(samples[quarter:2 * quarter]), max(samples[2 * quarter:])
    assert late - settled < 12 * 1024, (settled, late)

    files = sorted(windows.glob("day.trigger-*.mcap"))
    metas = [read_trigger(str(f)) for f in files]
    assert len(files) >= HOURS * 2 and all(m["pre_complete"] and m["post_complete"] for m in metas[1:-1])
    spans = [(m["start_t"], m["end_t"]) for m in metas]
    # the capture's frames over each window's span, as the simulator recorded them (`day_frames`: the day's
    # /frames, which no replay wrote)
    faults = [t for t, _raw, fault in day_frames if fault]
    day_keys = [(t, raw) for t, raw, _fault in day_frames]
    for path, m in zip(files, metas, strict=True):
        held = [(round(r["t"], 9), r["raw"]) for r in frames_of(path)]
        assert window_holds(held, day_keys, m["start_t"], m["end_t"]), path.name
        for firing in m["firings"]:
            assert (round(firing["record"]["t"], 9), firing["record"]["raw"]) in held
        assert m["end_t"] - m["trigger_t"] >= 60 - 1e-6
        assert m["trigger_t"] - m["start_t"] >= 300 - 1e-6 or not m["pre_complete"]
    assert faults and all(any(lo <= t <= hi for lo, hi in spans) for t in faults)  # no fault left out
    # a trip shows in two polls or more before the PLC resets it: the rate joins the fault's window
    assert any(m["rules"] == ["fault", "rate(fault) >= 2/5s"] for m in metas)
    assert f"{len(files)} window files" in err


def test_the_day_rotated_hourly_with_triggers_replays_whole(day, day_frames, tmp_path):
    """The same four hours through `replay --rotate 1h --trigger fault`, the path a live capture left for the
    night takes: one segment an hour (each replays alone), the set replayed as one capture is the day, frame
    for frame, and the trigger windows are written beside it, each holding its fault."""
    out, windows = tmp_path / "night", tmp_path / "windows"
    windows.mkdir()
    r = subprocess.run(SNIFFER + ["replay", str(day), "--quiet", "--rotate", "1h", "--out", str(out),
                                  "--windows", str(windows), "--trigger", "fault", "--pre", "2m", "--post", "30s"],
                       capture_output=True, text=True, timeout=LOADED_S)
    assert r.returncode == 0, r.stderr
    segments = sorted(out.glob("*.mcap"))
    assert HOURS <= len(segments) <= HOURS + 1, [s.name for s in segments]
    assert (out / "index.json").exists()
    opened = decode_capture(day)
    t0 = opened.info.t0_ns  # the day's clock (its metadata: nothing decoded)
    opened.close()
    whole = []
    for seg in segments:  # each alone: its frames are a run of the day's, in order
        alone = [(round((f.t_ns - t0) / 1e9, 9), f.raw.hex()) for f in decode_capture(seg)]
        assert alone, seg.name
        whole += alone
    # the same bytes at the same times: one clock across the segments
    assert whole == [(t, raw) for t, raw, _ in day_frames]
    as_one = subprocess.run(SNIFFER + ["replay", str(out), "--format", "jsonl"], capture_output=True, text=True,
                            timeout=LOADED_S)
    assert as_one.returncode == 0, as_one.stderr
    assert len(as_one.stdout.splitlines()) == len(day_frames)
    files = sorted(windows.glob("*.trigger-*.mcap"))
    assert len(files) >= HOURS * 2
    for path in files:
        m = read_trigger(str(path))
        held = {r["raw"] for r in frames_of(path)}
        assert all(firing["record"]["raw"] in held for firing in m["firings"]), path.name
