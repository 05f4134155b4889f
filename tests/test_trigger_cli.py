"""`--trigger` on the command line: a simulated capture replayed with triggers, `--on-trigger` with real
commands (one that works, one that fails, one that hangs), and flags that cannot work."""

import os
import subprocess
import sys
import time

import pytest

from sniffer.formats.mcap.reader import read_frames
from sniffer.triggers import read_trigger
from helpers import frames_of, window_holds

SNIFFER = [sys.executable, "-m", "sniffer"]


def run(*args, timeout=300, **kw):
    return subprocess.run(SNIFFER + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, **kw)


@pytest.fixture(scope="module")
def tds(tmp_path_factory):
    """Two simulated TDS-V8 drives for 120 s: they trip now and then (model.fault), the PLC resets them; with
    the capture's frame records (its /frames, as `simulate` decoded them: the reference no replay wrote)."""
    path = tmp_path_factory.mktemp("tds") / "tds.mcap"
    r = run("simulate", "--scenario", "tds-v8", "--duration", "120", "--seed", "3", "--out", path)
    assert r.returncode == 0, r.stderr
    return path, read_frames(str(path))


def _check_windows(folder, records, pre, post):
    """Every window holds its trigger frames and every frame of the capture from its start (at or up to a
    second before trigger - pre) to its end (last match + post); returns the metadata."""
    metas = []
    for path in sorted(folder.glob("*.trigger-*.mcap")):
        m = read_trigger(str(path))
        held = frames_of(path)  # a window has no /frames: what it replays to alone
        keys = [(r["t"], r["raw"]) for r in held]
        for firing in m["firings"]:
            assert (firing["record"]["t"], firing["record"]["raw"]) in keys
            assert firing["record"]["annotations"]  # a fault: the frame says so
        assert m["end_t"] >= m["trigger_t"] + post - 1e-6
        if m["pre_complete"]:
            assert m["asked_start_t"] - 1.0 <= m["start_t"] <= m["asked_start_t"] == pytest.approx(m["trigger_t"] - pre)
        assert window_holds(keys, [(r["t"], r["raw"]) for r in records], m["start_t"], m["end_t"])
        metas.append(m)
    return metas


def test_replay_with_trigger_fault_writes_one_window_per_event(tds, tmp_path):
    path, records = tds
    r = run("replay", path, "--trigger", "fault", "--pre", "10s", "--post", "4s", "--windows", tmp_path, "--quiet")
    assert r.returncode == 0, r.stderr
    assert r.stdout == ""
    metas = _check_windows(tmp_path, records, 10, 4)
    assert len(metas) >= 3 and all(m["rules"] == ["fault"] for m in metas)
    faults = [x for x in records if any(a["code"] == "model.fault" for a in x["annotations"])]
    # every fault frame is in a window, and each window's first firing is a fault that fired
    covered = [f for f in faults if any(m["start_t"] <= f["t"] <= m["end_t"] for m in metas)]
    assert covered == faults
    assert sum(m["matches"]["fault"] for m in metas) <= len(faults)
    assert f"triggers: {sum(m['firings_total'] for m in metas)} fired, {len(metas)} window files" in r.stderr


def test_without_ring_the_stream_goes_on_and_with_ring_a_capture_writes_only_windows(tds, tmp_path):
    path, records = tds
    r = run("replay", path, "--trigger", "fault", "--pre", "2s", "--post", "1s", "--windows", tmp_path)
    assert r.returncode == 0 and len(r.stdout.splitlines()) == len(records)
    out = tmp_path / "demo.mcap"
    r = run("demo", "--headless", "--quiet", "--scenario", "errors", "--duration", "4", "--out", out,
            "--trigger", "crc", "--pre", "1s", "--post", "0.5s", "--ring", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert not out.exists() and not list(tmp_path.glob("demo.mcap*"))
    windows = sorted(tmp_path.glob("demo.trigger-*.mcap"))
    assert windows and all(read_trigger(str(w))["rules"] == ["crc"] for w in windows)


SCRIPT = """#!/bin/sh
printf '%s|%s|%s|%s|%s\\n' "$SNIFFER_TRIGGER_FILE" "$SNIFFER_TRIGGER_RULE" "$SNIFFER_TRIGGER_TIME" \
    "$SNIFFER_TRIGGER_FRAME" "$SNIFFER_TRIGGER_SUMMARY" >> "$LOG"
"""


def test_on_trigger_runs_a_script_with_the_window_in_its_environment(tds, tmp_path):
    """Unit 2's faults: 7 windows, fewer than the runner's queue holds (a replay makes them faster than the
    commands run: past QUEUE waiting, one is dropped and reported, tested below)."""
    path, records = tds
    script = tmp_path / "got.sh"
    script.write_text(SCRIPT)
    script.chmod(0o755)
    log = tmp_path / "log.txt"
    r = run("replay", path, "--trigger", "fault u:2", "--pre", "5s", "--post", "2s", "--windows", tmp_path, "--quiet",
            "--on-trigger", str(script), env={**os.environ, "LOG": str(log)})
    assert r.returncode == 0, r.stderr
    windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
    lines = log.read_text().splitlines()
    assert len(lines) == len(windows) >= 3
    for line, w in zip(sorted(lines), windows, strict=True):
        file, rule, when, frame, summary = line.split("|", 4)
        m = read_trigger(str(w))
        first = m["firings"][0]
        assert file == str(w.resolve()) and rule == "fault u:2" and int(frame) == first["frame"]
        assert when == f"{first['t']:.6f}s" and summary == first["summary"] and "model.fault" in summary
    assert "on-trigger" not in r.stderr


def test_on_trigger_failures_are_one_line_each_and_the_capture_goes_on(tds, tmp_path):
    path, _ = tds
    r = run("replay", path, "--trigger", "fault u:2", "--pre", "5s", "--post", "2s", "--windows", tmp_path, "--quiet",
            "--on-trigger", "echo cannot reach the server; exit 3")
    assert r.returncode == 0, r.stderr
    windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
    failed = [x for x in r.stderr.splitlines() if "on-trigger:" in x]
    assert len(failed) == len(windows) >= 3
    assert all("exited with status 3" in x and x.endswith("cannot reach the server") for x in failed)
    assert "Traceback" not in r.stderr


def test_a_command_that_hangs_is_killed_with_its_children_after_the_timeout(tds, tmp_path):
    path, _ = tds
    marker = tmp_path / "marker"
    r = run("replay", path, "--trigger", "fault", "--pre", "5s", "--post", "2s", "--windows", tmp_path, "--quiet",
            "--max-window", "20s", "--on-trigger", f"(sleep 2; touch {marker}) & sleep 60",
            "--on-trigger-timeout", "0.5s")
    assert r.returncode == 0, r.stderr
    windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
    killed = [x for x in r.stderr.splitlines() if "killed after 0.5 s" in x]
    dropped = [x for x in r.stderr.splitlines() if "16 commands waiting; not run for" in x]
    assert len(killed) + len(dropped) == len(windows) > 17 and killed  # more windows than the queue holds
    assert len(killed) >= 17  # the running one and the 16 waiting: a replay outruns the commands
    time.sleep(2.5)
    assert not marker.exists()  # the whole process group went, the background child too


@pytest.mark.parametrize("flags,says", [
    (["--trigger", "u:1 >"], "--trigger 'u:1 >': filter error at column 5"),
    (["--trigger", "rate(crc) > 5"], "filter error at column 13: a rate is a count per time"),
    (["--trigger", "zzz:1"], "unknown key"),
    (["--trigger", ""], "empty rule"),
    (["--ring"], "--ring needs --trigger"),
    (["--on-trigger", "true"], "--on-trigger needs --trigger"),
    (["--trigger", "crc", "--pre", "5 parsecs"], "--pre '5 parsecs'"),
    (["--trigger", "crc", "--post", "2d"], "--post '2d'"),
    (["--trigger", "crc", "--post", "1m", "--max-window", "30s"], "shorter than --post"),
    (["--trigger", "crc", "--ring-max", "lots"], "not a size"),
    (["--trigger", "crc", "--windows", "/nonexistent/folder"], "not a folder"),
])
def test_bad_trigger_flags_are_one_error_line_and_exit_2(tds, tmp_path, flags, says):
    path, _ = tds
    for argv in (["replay", path], ["live", tmp_path / "no-such-port"]):
        r = run(*argv, *flags, "--quiet")
        lines = [x for x in r.stderr.splitlines() if x.strip()]
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("sniffer: error:"), r.stderr
        assert says in lines[0] and "Traceback" not in r.stderr
    assert not list(tmp_path.glob("*.mcap*"))


def test_windows_folder_is_made_when_its_parent_exists(tds, tmp_path):
    """`--windows DIR` makes DIR (one level, as --rotate makes its folder); a path whose parent is missing
    too is a typo: one line (the bad-flags test)."""
    path, _ = tds
    folder = tmp_path / "windows"
    r = run("replay", path, "--quiet", "--trigger", "fault", "--pre", "10s", "--post", "5s", "--windows", folder)
    assert r.returncode == 0, r.stderr
    assert folder.is_dir() and list(folder.glob("*.trigger-*.mcap"))


_MAX_RSS = """
import resource, subprocess, sys
r = subprocess.run(sys.argv[1:], capture_output=True, text=True,
                   preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)))
sys.stderr.write(r.stderr)
print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"""


def test_a_command_that_prints_without_end_costs_no_memory(tds, tmp_path):
    """`yes` for 1.5 s per window: its output is shown on stderr up to a cap and the rest dropped as it is
    read (the capture may never take more than 3 GB here: what an unbounded buffer would reach first)."""
    path, _ = tds
    r = subprocess.run([sys.executable, "-c", _MAX_RSS, *SNIFFER, "replay", str(path), "--trigger", "fault u:2",
                        "--pre", "5s", "--post", "2s", "--windows", str(tmp_path), "--quiet",
                        "--on-trigger", "yes", "--on-trigger-timeout", "1.5s"], capture_output=True, text=True,
                       timeout=300)
    rc, max_rss_kb = map(int, r.stdout.split())
    assert rc == 0, r.stderr[-2000:]
    assert max_rss_kb < 400 * 1024
    windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
    killed = [x for x in r.stderr.splitlines() if "'yes' killed after 1.5 s" in x]
    shown = [x for x in r.stderr.splitlines() if x.startswith("sniffer: on-trigger| ")]
    assert len(killed) == len(windows) >= 3
    assert len(shown) <= 50 * len(windows) and shown[0] == "sniffer: on-trigger| y"  # a few lines each
    assert sum("more lines not shown" in x for x in shown) == len(windows)


def test_a_command_shows_its_output_and_a_failure_quotes_its_last_line(tds, tmp_path):
    path, _ = tds
    r = run("replay", path, "--trigger", "fault u:2", "--pre", "5s", "--post", "2s", "--windows", tmp_path, "--quiet",
            "--on-trigger", "echo uploading; printf 'x%.0s' $(seq 1000); echo; echo 'no route to host' >&2; exit 1")
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
    assert lines.count("sniffer: on-trigger| uploading") == len(windows) >= 3
    long = [x for x in lines if x.startswith("sniffer: on-trigger| xxx")]
    assert len(long) == len(windows) and all(x.endswith(" ...") and len(x) < 400 for x in long)
    failed = [x for x in lines if x.startswith("sniffer: on-trigger: ")]
    assert len(failed) == len(windows) and all(x.endswith("exited with status 1 (window "
                                                          + x.split("(window ", 1)[1].split(")")[0]
                                                          + "): no route to host") for x in failed)


@pytest.mark.parametrize("command,timeout", [
    ("setsid sh -c 'echo $$ >> \"$PIDS\"; exec sleep 60' &", "60s"),  # the shell ends, its child keeps the pipe
    ("setsid sh -c 'echo $$ >> \"$PIDS\"; exec sleep 60' & sleep 60", "0.5s"),  # the shell is killed at 0.5 s
])
def test_a_child_that_leaves_the_group_with_the_pipe_does_not_hold_the_capture(tds, tmp_path, command, timeout):
    """A child in a session of its own escapes the group kill and keeps the output pipe open: the runner stops
    reading it (shortly after the shell ends, or at the timeout) instead of waiting for the child to end.
    Seven windows whose commands each kept the pipe 60 s took 7 minutes; the replay is bounded here by
    the test's own timeout, far under one such minute per window."""
    path, _ = tds
    pids = tmp_path / "pids"
    try:
        r = run("replay", path, "--trigger", "fault u:2", "--pre", "5s", "--post", "2s", "--windows", tmp_path,
                "--quiet", "--on-trigger", command, "--on-trigger-timeout", timeout, timeout=50,
                env={**os.environ, "PIDS": str(pids)})
        assert r.returncode == 0, r.stderr
        windows = sorted(tmp_path.glob("tds.trigger-*.mcap"))
        assert len(windows) >= 3
        killed = [x for x in r.stderr.splitlines() if "killed after 0.5 s" in x]
        assert len(killed) == (len(windows) if timeout == "0.5s" else 0)
    finally:
        for pid in (pids.read_text().split() if pids.exists() else ()):  # the children this test started
            try:
                os.kill(int(pid), 9)
            except OSError:
                pass
