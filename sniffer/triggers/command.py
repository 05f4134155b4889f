"""`--on-trigger CMD`: a command for each complete window file, run beside the capture, never in its way.

The command runs under `/bin/sh -c` in a process group of its own, one at a time on a thread of
its own, with the window in its environment (SNIFFER_TRIGGER_FILE, _RULE, _RULES, _TIME, _T,
_FRAME, _SUMMARY, _WINDOW), stdin from /dev/null and its output kept (the last line is quoted if
it fails).  It is killed (the whole group) after `timeout_s`.  At most QUEUE windows wait; one
more is not run.  Each failure (exit status, signal, timeout, cannot start, queue full) is one
line on stderr and counted; the capture goes on.  `close()` lets the queued commands finish
(each within its timeout).
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import threading

QUEUE = 16
_STOP = object()


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
                                    start_new_session=True, close_fds=True)
        except OSError as e:
            self._fail(f"cannot start {self.command!r}: {e.strerror or e}")
            return
        with self._lock:
            self.ran += 1
        try:
            out, _ = proc.communicate(timeout=self.timeout_s)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            proc.communicate()
            self._fail(f"{self.command!r} killed after {self.timeout_s:g} s (window {window})", timed_out=True)
            return
        if proc.returncode:
            how = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
                   else f"exited with status {proc.returncode}")
            last = (out or b"").decode("utf-8", "replace").strip().splitlines()[-1:] or [""]
            self._fail(f"{self.command!r} {how} (window {window}){': ' + last[0][:200] if last[0] else ''}")

    def _fail(self, text: str, *, timed_out: bool = False, dropped: bool = False) -> None:
        with self._lock:
            self.failed += 1
            self.timed_out += timed_out
            self.dropped += dropped
            self.last_error = text
        self.report(f"on-trigger: {text}")


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except OSError:
        proc.kill()


__all__ = ["CommandRunner", "QUEUE"]
