"""A capture as a process of its own, publishing to viewers: what `sniffer serve` and every live TUI run.

Why a process: a viewer in the capture's interpreter takes the interpreter from
the reader thread, so reads come late and frames glue (a late read holds a
request and its answer together: the answer loses its latency).  So `sniffer live`
/ `sniffer demo` with the TUI, and `sniffer serve`, start the capture as
`python -m sniffer live|demo` publishing on SOCKET, headless and quiet, and view
it over the socket like `sniffer attach`.  The child's whole CaptureSpec comes
on its stdin (`sniffer live|demo --spec-from-stdin`, CaptureSpec.encode): the
flags are parsed once, in the command the user typed.  The child:

* runs in a session of its own (a Ctrl-C typed at the terminal reaches the
  viewer, which decides), and gets SIGINT from the kernel if its parent dies
  (processes/parent_death.py), so a killed viewer still leaves a closed, readable MCAP;
* owns the port and the file; the parent never opens either;
* says what it has to say on stderr, which the parent relays: at once before
  the viewer takes the terminal, held (and shown as notifications) while it has
  it, printed after it gives it back.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable

from sniffer.processes.stream import parse_address

WAIT_FOR_CAPTURE_S = 30.0
STOP_WAIT_S = 15.0


def capture_argv(command: str) -> list[str]:
    """The command line of the capture process; its CaptureSpec follows on stdin (capture_input)."""
    return [sys.executable, "-m", "sniffer", command, "--spec-from-stdin"]


def capture_input(spec, sock: str) -> bytes:
    """What the capture process reads on stdin: `spec`, publishing on `sock`, with no stream and no TUI."""
    return spec.with_(publish=sock, headless=True, stream=None).encode()


def publishing(sock: str) -> bool:
    """Something accepts connections at `sock` (a Unix socket path or tcp:[HOST:]PORT)."""
    from sniffer.processes.attach import connect
    from sniffer.events import CaptureError

    try:
        connect(parse_address(sock), 1.0).close()
    except CaptureError:
        return False
    return True


class StderrRelay:
    """The child's stderr, line by line: printed at once, or held while a viewer owns the terminal."""

    def __init__(self, pipe) -> None:
        self.pipe = pipe
        self.held: list[str] = []
        self.on_line: Callable[[str], None] | None = None  # while held: also told each line (notifications)
        self._hold = False
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name="capture-stderr", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for raw in iter(self.pipe.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip("\n")
            with self._lock:
                if self._hold:
                    self.held.append(line)
                    tell = self.on_line
                else:
                    print(line, file=sys.stderr, flush=True)
                    tell = None
            if tell is not None:
                try:
                    tell(line)
                except Exception:  # noqa: BLE001 - the viewer is closing: the line is held anyway
                    pass
        self.pipe.close()

    def hold(self, on_line: Callable[[str], None] | None = None) -> None:
        with self._lock:
            self._hold, self.on_line = True, on_line

    def release(self, timeout_s: float = 5.0, *, wait_eof: bool = False) -> None:
        """Print what was held, and print from now on (`wait_eof`: first wait for the child to close stderr)."""
        if wait_eof:
            self._thread.join(timeout_s)
        with self._lock:
            self._hold, self.on_line = False, None
            held, self.held = self.held, []
        for line in held:
            print(line, file=sys.stderr)
        sys.stderr.flush()


class CaptureProcess:
    """`sniffer COMMAND` started as the capture of `spec`, publishing on `sock`: wait_publishing(), then view
    `sock`; stop() as Ctrl-C would."""

    def __init__(self, spec, command: str, sock: str, *, relay_stderr: bool = False) -> None:
        from sniffer.processes.parent_death import die_with_parent

        self.sock = sock
        self.argv = capture_argv(command)
        # its own session: the terminal's Ctrl-C is the viewer's to handle; SIGINT if we die (closes its MCAP)
        self.child = subprocess.Popen(self.argv, stdin=subprocess.PIPE,
                                      stdout=subprocess.DEVNULL if relay_stderr else None,
                                      stderr=subprocess.PIPE if relay_stderr else None,
                                      start_new_session=relay_stderr,
                                      preexec_fn=lambda: die_with_parent(signal.SIGINT))
        try:  # the spec, then end of file: the child reads it whole before it starts (never the terminal)
            self.child.stdin.write(capture_input(spec, sock))
            self.child.stdin.close()
        except BrokenPipeError:  # it died at once: wait_publishing() says so, and it said why on stderr
            pass
        self.stderr = StderrRelay(self.child.stderr) if relay_stderr else None

    @property
    def returncode(self) -> int | None:
        return self.child.poll()

    def wait_publishing(self, timeout_s: float = WAIT_FOR_CAPTURE_S) -> bool:
        """True once the capture publishes; False if it exited first (it said why on stderr)."""
        deadline = time.monotonic() + timeout_s
        while not publishing(self.sock):
            if self.child.poll() is not None:
                return False
            if time.monotonic() > deadline:
                print(f"sniffer: error: the capture did not publish on {self.sock} within {timeout_s:.0f} s",
                      file=sys.stderr)
                self.stop()
                return False
            time.sleep(0.05)
        return True

    def stop(self, timeout_s: float = STOP_WAIT_S, *, ending: bool = False) -> int:
        """Ask the capture to stop as Ctrl-C would (it closes its MCAP), then wait for it.  `ending`: it said
        it has ended, so it is only exiting: wait for that first (a SIGINT while Python shuts down kills it)."""
        child = self.child
        if ending:
            try:
                child.wait(timeout_s)
            except subprocess.TimeoutExpired:
                pass
        if child.poll() is None:
            child.send_signal(signal.SIGINT)
            try:
                child.wait(timeout_s)
            except subprocess.TimeoutExpired:
                print("sniffer: the capture did not stop; killing it (its MCAP stays readable: sniffer repair)",
                      file=sys.stderr)
                child.kill()
                child.wait()
        return child.returncode

    def rc(self) -> int:
        """The capture's exit status as this command's: a signal that killed it is a failure."""
        rc = self.child.returncode
        return 1 if rc is None or rc < 0 else rc


def private_socket() -> tuple[str, Callable[[], None]]:
    """A socket path only this user can reach (a fresh 0700 directory), and a cleanup for it."""
    import shutil
    import tempfile

    where = os.environ.get("XDG_RUNTIME_DIR")
    d = tempfile.mkdtemp(prefix="sniffer-", dir=where if where and os.path.isdir(where) else None)
    return os.path.join(d, "capture.sock"), lambda: shutil.rmtree(d, ignore_errors=True)
