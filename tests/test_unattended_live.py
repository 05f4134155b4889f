"""Unattended capture for real: processes killed with SIGKILL, an adapter unplugged and plugged back (a
simulated line on a pty that goes away and comes back), a long simulated run whose memory stays flat.

Checks what happened, not when: the tests wait for files and states, never assert a time.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from sniffer.capture.session import decode_capture
from sniffer.formats.mcap.segments import INDEX_NAME, STATUS_NAME

SNIFFER = [sys.executable, "-m", "sniffer"]
HANG_S = 60  # a state not reached by then is a failure, not a slow machine
ROOT = Path(__file__).resolve().parent.parent


def run(*args, timeout=120):
    return subprocess.run(SNIFFER + [str(a) for a in args], capture_output=True, text=True, timeout=timeout)


def wait_until(what: str, check, timeout_s: float = HANG_S):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        got = check()
        if got:
            return got
        time.sleep(0.1)
    raise AssertionError(f"never happened: {what}")


def read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def closed_segments(folder: Path) -> list[dict]:
    d = read_json(folder / INDEX_NAME) or {}
    return [s for s in d.get("segments", ()) if s["state"] == "closed"]


def assert_complete(path: Path) -> None:
    with open(path, "rb") as fh:  # the indexed reader needs the summary and footer a finished file has
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics.message_count > 0, path


@pytest.mark.parametrize("closed_before_kill", [0, 3])
def test_sigkill_leaves_closed_segments_whole_and_the_open_one_repairable(tmp_path, closed_before_kill):
    """`sniffer demo` (the simulated bus over a pty, captured live) with --rotate 1s, killed with SIGKILL."""
    folder = tmp_path / "cab"
    proc = subprocess.Popen(SNIFFER + ["demo", "--headless", "--quiet", "--duration", "120", "--rotate", "1s",
                                       "--out", str(folder)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_until("the capture started", lambda: (read_json(folder / STATUS_NAME) or {}).get("state") == "running")
        wait_until(f"{closed_before_kill} segments closed", lambda: len(closed_segments(folder)) >= closed_before_kill)
        if closed_before_kill:
            r = run("status", folder)
            assert r.returncode == 0 and ": running" in r.stdout.splitlines()[0], r.stdout
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    proc.stderr.close()
    closed = closed_segments(folder)
    assert len(closed) >= closed_before_kill
    for seg in closed:  # each replays whole (in this process: a segment every second piles up under load)
        assert_complete(folder / seg["file"])
        assert sum(1 for _ in decode_capture(folder / seg["file"])) == seg["frames"] > 0, seg
    parts = sorted(folder.glob("*.mcap.part"))
    assert len(parts) <= 1  # the one open when killed (none if killed between two segments)
    whole = run("replay", folder, "--format", "jsonl")
    assert whole.returncode == 0, whole.stderr
    frames = [json.loads(line) for line in whole.stdout.splitlines()]
    assert [f["index"] for f in frames] == list(range(len(frames)))
    assert len(frames) >= sum(s["frames"] for s in closed)
    r = run("status", folder)
    assert r.returncode == 1 and "not running: its process" in r.stdout
    for part in parts:
        r = run("repair", part)  # the open segment, finished under the name it would have had
        assert r.returncode == 0, r.stderr
        assert_complete(Path(str(part)[: -len(".part")]))
    # a capture started again in the folder (systemd's restart) continues it: the killed run's segments stay
    r = run("demo", "--headless", "--quiet", "--duration", "2", "--rotate", "1s", "--out", folder)
    assert r.returncode == 0, r.stderr
    index = json.loads((folder / INDEX_NAME).read_text())["segments"]
    assert len({s["capture_id"] for s in index}) == 2 and all(s["state"] == "closed" for s in index)
    again = run("replay", folder, "--format", "jsonl")
    recs = [json.loads(line) for line in again.stdout.splitlines()]
    assert again.returncode == 0 and len(recs) > len(frames)
    gaps = [(i, a["detail"]) for i, r in enumerate(recs) for a in r["annotations"] if a["code"] == "source.gap"]
    if frames:  # the restart is a hole in the one capture the folder replays as
        assert len(gaps) == 1 and gaps[0][0] >= len(frames) - 5 and "another capture starts" in gaps[0][1]


def _plug(link) -> subprocess.Popen:
    """A simulated line appears at `link` (an adapter plugged in), until SIGTERM (unplugged)."""
    return subprocess.Popen(SNIFFER + ["simulate", "--pty", str(link), "--scenario", "default"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _status(folder: Path) -> dict:
    return read_json(folder / STATUS_NAME) or {}


def test_wait_port_waits_for_every_port_of_a_multi_link_capture(tmp_path):
    """live A B --wait-port with neither line there: it waits on through A coming (B still missing), then
    captures both links once B comes too."""
    a, b, status, out = tmp_path / "ttyA", tmp_path / "ttyB", tmp_path / "st.json", tmp_path / "two.mcap"
    live = subprocess.Popen(SNIFFER + ["live", str(a), str(b), "--wait-port", "--baud", "19200", "--parity", "E",
                                       "--status", str(status), "--out", str(out), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    sims = []

    def plug(link):
        sims.append(_plug(link))

    try:
        st = wait_until("waiting for both", lambda: (read_json(status) or {}).get("port", {}).get("missing")
                        == [str(a), str(b)] and read_json(status))
        assert st["state"] == "waiting for port" and st["port"]["path"] == str(a)
        plug(a)
        wait_until("waiting for B alone", lambda: (read_json(status) or {}).get("port", {}).get("missing")
                   == [str(b)])
        assert live.poll() is None  # A alone did not start it, nor end it with "no such port"
        plug(b)
        wait_until("frames", lambda: (read_json(status) or {}).get("frames", 0) > 40)
    finally:
        live.send_signal(signal.SIGTERM)
        rc = live.wait(timeout=30)
        err = live.stderr.read()
        for sim in sims:
            sim.send_signal(signal.SIGTERM)
            sim.wait(timeout=20)
    assert rc == 0, err
    said = [line for line in err.splitlines() if line.strip()]
    assert said[:2] == [f"sniffer: {p}: not there (adapter unplugged?); waiting for it (--wait-port)" for p in (a, b)]
    r = run("replay", out, "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    assert {json.loads(x)["link"] for x in r.stdout.splitlines()} == {"ttyA", "ttyB"}


def test_wait_for_the_port_and_survive_an_unplug(tmp_path):
    """live --wait-port on a line that is not there yet; the line goes away (the adapter unplugged) and
    comes back at the same path; SIGTERM ends the capture with every segment closed."""
    link, folder = tmp_path / "ttyRS485", tmp_path / "plant"
    live = subprocess.Popen(SNIFFER + ["live", str(link), "--wait-port", "--baud", "19200", "--parity", "E",
                                       "--rotate", "2s", "--keep", "20", "--out", str(folder), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    sims = []

    def plug():
        sims.append(_plug(link))

    try:
        st = wait_until("waiting for the port", lambda: _status(folder).get("state") == "waiting for port"
                        and _status(folder))
        assert st["port"]["state"] == "absent" and st["port"]["path"] == str(link)
        plug()
        first = wait_until("frames", lambda: _status(folder).get("frames", 0) > 20 and _status(folder))
        assert first["state"] == "running" and first["port"] == {"state": "ok"}
        sims[-1].send_signal(signal.SIGTERM)  # unplugged: the line and its link go away
        assert sims[-1].wait(timeout=20) == 0
        lost = wait_until("the port lost", lambda: _status(folder).get("port", {}).get("state") == "lost"
                          and _status(folder))
        assert lost["state"] == "running" and live.poll() is None  # still capturing, waiting for the adapter
        plug()
        wait_until("the port back", lambda: _status(folder).get("port", {}).get("state") == "ok"
                   and _status(folder).get("errors", {}).get("gaps") == 1)
        before = _status(folder)["frames"]
        wait_until("frames after the replug", lambda: _status(folder).get("frames", 0) > before + 20)
    finally:
        live.send_signal(signal.SIGTERM)
        rc = live.wait(timeout=30)
        err = live.stderr.read()
        for sim in sims:
            if sim.poll() is None:
                sim.send_signal(signal.SIGTERM)
            sim.wait(timeout=20)
    assert rc == 0, err
    said = [line for line in err.splitlines() if line.strip()]
    assert said[0] == f"sniffer: {link}: not there (adapter unplugged?); waiting for it (--wait-port)"
    # the tty hangs up, then its link goes: the reader sees the hang-up, or (if it looked at the path just
    # between the two) the path gone; either is the unplug
    assert any(line in said for line in (f"sniffer: {link}: port lost ({why}); waiting for it to come back"
                                         for why in ("hang-up (end of file)", "port path vanished")))
    assert f"sniffer: {link}: port back; capturing again" in said
    assert "Traceback" not in err
    for sim in sims:
        assert "0 bytes came from the other end" in sim.stderr.read()  # passive: the sniffer sent nothing
    st = _status(folder)
    assert st["state"] == "ended" and st["segments"]["open"] is None
    assert not list(folder.glob("*.part"))
    for seg in closed_segments(folder):
        assert_complete(folder / seg["file"])
    r = run("replay", folder, "--format", "jsonl")
    recs = [json.loads(line) for line in r.stdout.splitlines()]
    assert r.returncode == 0 and len(recs) == st["frames"]
    gaps = [a["detail"] for x in recs for a in x["annotations"] if a["code"] == "source.gap"]
    assert len(gaps) == 1 and "port lost" in gaps[0]


def test_memory_stays_flat_over_hundreds_of_segments():
    """Twelve minutes of the simulated bus in 2 s segments (360 of them, --keep 5: 355 deleted) through the
    session code, in a process of its own: the objects alive and the RSS do not grow with the segments.
    (Segments of 2 s, not 10 s over an hour: the same 360 rotations, each opening, closing, indexing and
    deleting a file, for a fifth of the frames to simulate and decode.)"""
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_unattended.py"), "--child", "rotated",
                        "--duration", "720", "--rotate", "2s", "--keep", "5", "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["error"] is None and got["files"] == 5 and got["frames"] > 60_000
    samples = got["samples"]
    assert len(samples) >= 360

    def mean(xs):
        return sum(xs) / len(xs)

    early, late = samples[50:100], samples[-50:]
    # a leak of a few objects per segment would add thousands over the 260 segments between the two
    assert mean([s["objects"] for s in late]) - mean([s["objects"] for s in early]) < 1000
    assert max(s["rss_mib"] for s in late) - max(s["rss_mib"] for s in early) < 4.0


@pytest.mark.parametrize("reader", ["process", "thread"])
def test_an_unplug_is_said_when_it_happens_without_a_status_file(tmp_path, reader):
    """No --status, no --rotate: stderr still says the port went away when it goes (not at the end), and
    that it came back when it comes; the reader in a process of its own or a thread of the capture."""
    import os
    import threading

    link, out = tmp_path / "ttyRS485", tmp_path / "plant.mcap"
    env = {**os.environ, "SNIFFER_READER": reader}
    live = subprocess.Popen(SNIFFER + ["live", str(link), "--wait-port", "--baud", "19200", "--parity", "E",
                                       "--out", str(out), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    said: list[str] = []
    reading = threading.Thread(target=lambda: said.extend(iter(live.stderr.readline, "")), daemon=True)
    reading.start()
    sims = []
    try:
        wait_until("waiting for the port", lambda: any("waiting for it (--wait-port)" in x for x in said))
        sims.append(_plug(link))
        wait_until("capturing", lambda: any(" (read-only) -> " in x for x in said))
        time.sleep(1.0)  # some frames
        sims[-1].send_signal(signal.SIGTERM)
        assert sims[-1].wait(timeout=20) == 0
        lost = wait_until("the loss said", lambda: [x for x in said if ": port lost (" in x])
        assert live.poll() is None  # said while the capture goes on, waiting for the adapter
        assert lost[0].rstrip("\n") in (f"sniffer: {link}: port lost ({why}); waiting for it to come back"
                                        for why in ("hang-up (end of file)", "port path vanished"))
        sims.append(_plug(link))
        wait_until("the return said", lambda: f"sniffer: {link}: port back; capturing again\n" in said)
    finally:
        live.send_signal(signal.SIGTERM)
        rc = live.wait(timeout=30)
        reading.join(10)
        for sim in sims:
            if sim.poll() is None:
                sim.send_signal(signal.SIGTERM)
            sim.wait(timeout=20)
    assert rc == 0, said
    assert sum(": port lost (" in x for x in said) == 1 and sum(": port back" in x for x in said) == 1
    assert "Traceback" not in "".join(said)
