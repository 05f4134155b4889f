"""`--on-trigger CMD`: a command for each complete window file, run beside the capture, never in its way.

The command runs under `/bin/sh -c` in a process group of its own, one at a time on a thread of
its own, with the window in its environment (SNIFFER_TRIGGER_FILE, _RULE, _RULES, _TIME, _T,
_FRAME, _SUMMARY, _WINDOW) and stdin from /dev/null.  At most QUEUE windows wait; one more is not
run.  Each failure (exit status, signal, timeout, cannot start, queue full) is one line on stderr
and counted; the capture goes on.  `close()` lets the queued commands finish (each within its
timeout).

Its output (stdout and stderr) is read as it comes and goes to stderr as `on-trigger| LINE`: at
most MAX_LINES lines of at most LINE_CHARS characters per command, then one line saying how much
more there was; the rest is read and dropped, so a command that prints without end (`yes`) costs
no memory.  A failure's line quotes the command's last line.

`timeout_s` bounds everything a command may take: when it passes, the whole process group is
killed and its output pipe is no longer read.  A child that left the group (`setsid`, a daemon)
and keeps the pipe open does not hold the runner either: once the shell has exited its output is
read for at most PIPE_GRACE_S more, then the pipe is closed (the child, if it writes again, gets
SIGPIPE; redirect the output of what you start in the background).
"""

from __future__ import annotations

import os
import queue
import select
import signal
import subprocess
import threading
import time

QUEUE = 16
MAX_LINES = 20  # lines of a command's output shown on stderr
LINE_CHARS = 300  # characters of a line shown (and kept for the failure's line)
PIPE_GRACE_S = 0.5  # after the shell exits, how long its pipe is still read (a background child's last words)
_READ = 1 << 16
_STOP = object()


class _Lines:
    """A command's output as lines on stderr, within MAX_LINES x LINE_CHARS (bounded memory whatever comes)."""

    def __init__(self, say) -> None:
        self.say = say
        self.shown = 0
        self.hidden = 0  # lines past MAX_LINES, counted, not shown
        self.last = ""  # the last non-empty line (at most LINE_CHARS), for a failure's line
        self._buf = bytearray()  # the current line, at most LINE_CHARS bytes of it
        self._long = False  # the current line passed LINE_CHARS: the rest of it is dropped

    def feed(self, data: bytes) -> None:
        start = 0
        while start < len(data):
            if self.shown >= MAX_LINES:
                self._count(data[start:] if start else data)
                return
            nl = data.find(b"\n", start)
            end = len(data) if nl < 0 else nl
            self._add(data[start:end])
            if nl < 0:
                return
            self._line()
            start = nl + 1

    def finish(self) -> None:
        if self._buf or self._long:
            self._line()
        if self.hidden:
            self.say(f"on-trigger| ... ({self.hidden} more lines not shown)")

    def _add(self, piece: bytes) -> None:
        room = LINE_CHARS - len(self._buf)
        if len(piece) > room:
            self._long = True
        if room > 0:
            self._buf += piece[:room]

    def _count(self, data: bytes) -> None:
        """Past MAX_LINES: only count the lines and keep the last (no work per line: `yes` is cheap)."""
        nl = data.rfind(b"\n")
        if nl < 0:
            self._add(data)
            return
        self.hidden += data.count(b"\n", 0, nl + 1)
        prev = data.rfind(b"\n", 0, nl)
        if prev < 0:
            self._add(data[:nl])
            line = bytes(self._buf)
        else:
            line = data[prev + 1:nl][:LINE_CHARS]
        self._remember(line)
        self._buf = bytearray()
        self._long = False
        self._add(data[nl + 1:])

    def _remember(self, line: bytes) -> str:
        text = line.decode("utf-8", "replace").rstrip("\r")
        text = "".join(c if c.isprintable() else "?" for c in text)
        if text.strip():
            self.last = text.strip()
        return text

    def _line(self) -> None:
        text = self._remember(bytes(self._buf))
        cut = self._long
        self._buf = bytearray()
        self._long = False
        if self.shown < MAX_LINES:
            self.shown += 1
            self.say(f"on-trigger| {text}{' ...' if cut else ''}")
        else:
            self.hidden += 1


class CommandRunner:
    def __init__(self, command: str, timeout_s: float, report) -> None:
        self.command = command
        self.timeout_s = timeout_s
        self.report = report  # one line (str) -> stderr
        self.ran = self.failed = self.timed_out = self.dropped = 0
        self.last_error: str | None = None
        self._queue: queue.Queue = queue.Queue(QUEUE)
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._work, name="on-trigger", daemon=True)
        self._thread.start()

    def submit(self, env: dict[str, str]) -> bool:
        """Queue a run (False, reported and counted, when QUEUE runs are waiting already)."""
        try:
            self._queue.put_nowait(env)
            return True
        except queue.Full:
            self._fail(f"{QUEUE} commands waiting; not run for {env.get('SNIFFER_TRIGGER_FILE')}", dropped=True)
            return False

    def close(self) -> None:
        self._queue.put(_STOP)
        self._thread.join()

    def status(self) -> dict:
        with self._lock:
            return {"ran": self.ran, "failed": self.failed, "timed_out": self.timed_out, "dropped": self.dropped,
                    "last_error": self.last_error}

    # ------------------------------------------------------------ the thread
    def _work(self) -> None:
        while True:
            env = self._queue.get()
            if env is _STOP:
                return
            try:
                self._run(env)
            except Exception as e:  # noqa: BLE001 - a command's trouble never ends the capture
                self._fail(f"{type(e).__name__}: {e}")

    def _run(self, env: dict[str, str]) -> None:
        window = env.get("SNIFFER_TRIGGER_FILE", "")
        try:
            proc = subprocess.Popen(["/bin/sh", "-c", self.command], env={**os.environ, **env},
                                    stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    start_new_session=True, close_fds=True, bufsize=0)
        except OSError as e:
            self._fail(f"cannot start {self.command!r}: {e.strerror or e}")
            return
        with self._lock:
            self.ran += 1
        out = _Lines(lambda text: self.report(text))
        deadline = time.monotonic() + self.timeout_s
        try:
            _pump(proc, out, deadline)
            try:  # the pipe ended (or the shell ended a while ago): the shell has the rest of the time
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _kill_group(proc)  # before the pipe closes: the command ends by the timeout, not by SIGPIPE
                proc.wait()
                timed_out = True
            else:
                timed_out = False
        finally:
            proc.stdout.close()  # never waited for again: a child that keeps it gets SIGPIPE when it writes
        out.finish()
        if timed_out:
            self._fail(f"{self.command!r} killed after {self.timeout_s:g} s (window {window})", timed_out=True)
            return
        if proc.returncode:
            how = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
                   else f"exited with status {proc.returncode}")
            self._fail(f"{self.command!r} {how} (window {window}){': ' + out.last if out.last else ''}")

    def _fail(self, text: str, *, timed_out: bool = False, dropped: bool = False) -> None:
        with self._lock:
            self.failed += 1
            self.timed_out += timed_out
            self.dropped += dropped
            self.last_error = text
        self.report(f"on-trigger: {text}")


def _pump(proc: subprocess.Popen, out: _Lines, deadline: float) -> None:
    """Read the command's output into `out` until the pipe ends, the deadline passes, or the shell has
    exited PIPE_GRACE_S ago (a background child still holding the pipe)."""
    fd = proc.stdout.fileno()
    until = deadline
    while True:
        now = time.monotonic()
        if until == deadline and proc.poll() is not None:
            until = min(deadline, now + PIPE_GRACE_S)
        if now >= until:
            return
        ready, _, _ = select.select([fd], [], [], min(until - now, 0.1))
        if ready:
            data = os.read(fd, _READ)
            if not data:
                return
            out.feed(data)


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except OSError:
        proc.kill()


__all__ = ["CommandRunner", "QUEUE"]
