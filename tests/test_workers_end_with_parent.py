"""Worker processes end with the command that started them, even when it is killed outright (SIGKILL, the OOM
killer): `ingest --jobs` (a process pool) and `replay --jobs` (sniffer.parallel's part workers) leave nothing
behind decoding for nobody (sniffer/processes/parent_death.py).

The command runs in a session of its own, so whatever it started is found by its session id after it is gone.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from serve_helpers import processes_in_session
from terminal import children

WAIT_S = 60.0  # the workers' start on a loaded machine (they are killed long before they would finish)
GONE_S = 10.0  # the kernel's signal is at once, the watcher looks every half second: a loaded machine's margin


@pytest.fixture(scope="module")
def long_capture(tmp_path_factory):
    """A capture whose decoding takes each worker seconds, of several parts (sniffer.parallel.engine.PART_EVENTS)."""
    path = tmp_path_factory.mktemp("long") / "fast.mcap"
    r = subprocess.run([sys.executable, "-m", "sniffer", "simulate", "--out", str(path), "--scenario", "fast",
                        "--duration", "60", "--seed", "2"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return path


def _kill_when_working(argv: list[str], workers: int) -> int:
    """Start `sniffer ARGV`, SIGKILL it once `workers` worker processes run; its session id (its pid)."""
    proc = subprocess.Popen([sys.executable, "-m", "sniffer", *argv], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + WAIT_S
        while len(children(proc.pid)) < workers:
            assert proc.poll() is None, f"it ended before its workers were seen: {proc.stderr.read().decode()}"
            assert time.monotonic() < deadline, f"no {workers} workers within {WAIT_S:.0f} s"
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        return proc.pid
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stderr.close()


def _gone(sid: int) -> list[int]:
    """Wait for every process of session `sid` to end; what is left after GONE_S (each then killed)."""
    deadline = time.monotonic() + GONE_S
    while (left := processes_in_session(sid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    return left


def test_a_killed_ingest_leaves_no_worker(tmp_path, long_capture):
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    for i in range(4):  # copies: each is staged by a worker (the same bytes are skipped only at the commit)
        shutil.copy(long_capture, fleet / f"cab{i}.mcap")
    sid = _kill_when_working(["ingest", str(fleet), "--to", str(tmp_path / "ds"), "--jobs", "2"], 2)
    assert _gone(sid) == [], "an ingest killed outright left worker processes running"


def test_a_killed_parallel_replay_leaves_no_worker(tmp_path, long_capture):
    sid = _kill_when_working(["export", str(long_capture), "--to", "jsonl", "--out", str(tmp_path / "out.jsonl"),
                              "--jobs", "2"], 2)
    assert _gone(sid) == [], "a parallel export killed outright left worker processes running"


def test_a_worker_started_from_another_thread_is_ended_by_its_watcher():
    """PR_SET_PDEATHSIG follows the thread that started the worker, so a worker started from any other thread
    relies on the watcher alone: it ends once its parent is gone all the same."""
    from sniffer.processes.parent_death import worker_ends_with_parent

    r, w = os.pipe()
    middle = os.fork()
    if middle == 0:  # the parent of the worker: starts it, says its pid, waits to be killed
        try:
            os.close(r)
            worker = os.fork()
            if worker == 0:
                os.close(w)
                worker_ends_with_parent(os.getppid(), False)
                time.sleep(120)
                os._exit(0)
            os.write(w, str(worker).encode())
            time.sleep(120)
        finally:
            os._exit(0)
    os.close(w)
    worker = int(os.read(r, 32))  # the middle holds its end open: one read, not to the end
    os.close(r)
    os.kill(middle, signal.SIGKILL)
    os.waitpid(middle, 0)
    deadline = time.monotonic() + GONE_S
    while (state := _state(worker)) not in (None, "Z") and time.monotonic() < deadline:
        time.sleep(0.1)
    if state not in (None, "Z"):
        os.kill(worker, signal.SIGKILL)
    assert state in (None, "Z"), "the worker outlived its parent"


def _state(pid: int) -> str | None:
    from terminal import stat_fields

    fields = stat_fields(pid)
    return fields[0] if fields else None
