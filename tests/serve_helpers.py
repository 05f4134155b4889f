"""Running `sniffer serve` as a process, and finding the processes a run leaves behind.

Used by tests/test_serve.py, tests/test_serve_chromium.py and benchmarks/bench_tui.py.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

from terminal import stat_fields

HANG_S = 60  # a bound on waiting for something that should happen, never an assertion on speed


def wait(cond, what: str, timeout: float = HANG_S) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"gave up waiting for {what}"
        time.sleep(0.02)


def published(sock: str) -> int:
    """Frames the capture publishing at `sock` has given its viewers so far, as a viewer connecting now is told
    (its publisher process may still be taking what the capture handed over: PublishSink.frames)."""
    from sniffer.processes.attach import Attachment

    att = Attachment(sock)
    try:
        return att.earlier_frames + int(att.header["backlog_frames"])
    finally:
        att.close()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_serve(cwd: Path, *args: str, log: Path) -> tuple[subprocess.Popen, int]:
    """`sniffer serve ARGS` on a free port of 127.0.0.1, its stdout and stderr in `log`; returned once
    its web server answers (the capture publishes by then)."""
    port = free_port()
    with open(log, "w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "sniffer", "serve", *args, "--http-port", str(port)],
                                cwd=cwd, stdout=out, stderr=out, stdin=subprocess.DEVNULL)

    def up():
        assert proc.poll() is None, f"serve exited: {log.read_text()}"
        with socket.socket() as s:
            return s.connect_ex(("127.0.0.1", port)) == 0

    try:
        wait(up, "the web server")
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    return proc, port


def _live_processes():
    """(pid, command line, session id) of each live process (zombies left out)."""
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmd = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat_fields(pid)
        if fields is not None and fields[0] != "Z":
            yield int(pid), cmd, int(fields[3])


def processes_with(needle: str) -> list[int]:
    """Live processes whose command line holds `needle`."""
    return [pid for pid, cmd, _ in _live_processes() if needle in cmd]


def captures_of(server_pid: int) -> list[int]:
    """The capture processes `sniffer serve` (pid `server_pid`) started: `sniffer live|demo --spec-from-stdin`,
    its CaptureSpec on their stdin (sniffer/processes/capture.py)."""
    return [pid for pid, cmd, _ in _live_processes() if "--spec-from-stdin" in cmd
            and (stat_fields(pid) or [None, None])[1] == str(server_pid)]


def processes_in_session(sid: int) -> list[int]:
    """Live processes of session `sid` (what a process started with start_new_session=True left)."""
    return [pid for pid, _, session in _live_processes() if session == sid]
