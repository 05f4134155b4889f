"""A command on a pseudo-terminal of its own, as a user's terminal runs it (tests and benchmarks)."""

from __future__ import annotations

import fcntl
import os
import pty
import select
import struct
import subprocess
import termios
import time

HANG_S = 60.0


class Terminal:
    """A command on a pty of its own, as a terminal runs it: what it draws is read and kept, keys are typed."""

    def __init__(self, argv: list[str], cols: int = 120, rows: int = 40, cwd: str | None = None) -> None:
        self.master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
        env = dict(os.environ, TERM="xterm-256color", COLUMNS=str(cols), LINES=str(rows))
        env.pop("CI", None)  # Textual is the same either way; keep CI's own settings out of the App
        self.proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, env=env, start_new_session=True,
                                     close_fds=True, cwd=cwd)
        os.close(slave)
        self.screen = bytearray()

    def read(self, timeout_s: float = 0.1) -> None:
        while select.select([self.master], [], [], timeout_s)[0]:
            try:
                data = os.read(self.master, 65536)
            except OSError:  # EIO: the command closed the terminal
                return
            if not data:
                return
            self.screen += data
            timeout_s = 0

    def wait_for(self, text: str, timeout_s: float = HANG_S) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.read()
            if text.encode() in self.screen:
                return True
            if self.proc.poll() is not None:
                self.read()
                return text.encode() in self.screen
        return False

    def type(self, keys: str) -> None:
        os.write(self.master, keys.encode())

    def finish(self, timeout_s: float = HANG_S) -> int:
        deadline = time.monotonic() + timeout_s
        while self.proc.poll() is None and time.monotonic() < deadline:
            self.read()
        if self.proc.poll() is None:
            self.proc.kill()
        rc = self.proc.wait()
        self.read()
        os.close(self.master)
        return rc


def stat_fields(pid: int | str, tid: int | str | None = None) -> list[str] | None:
    """The fields of /proc/PID/stat (of thread TID: /proc/PID/task/TID/stat) after the command's name: [0] the
    state, [1] the parent, [3] the session, [16] the nice level; None once the process is gone."""
    path = f"/proc/{pid}/stat" if tid is None else f"/proc/{pid}/task/{tid}/stat"
    try:
        with open(path) as f:
            return f.read().rpartition(")")[2].split()
    except OSError:
        return None


def children(pid: int) -> list[int]:
    """The processes whose parent is `pid` (a TUI's capture child)."""
    out = []
    for p in os.listdir("/proc"):
        if p.isdigit():
            fields = stat_fields(p)
            if fields is not None and int(fields[1]) == pid:
                out.append(int(p))
    return out


def descendants(pid: int) -> list[int]:
    """Every process under `pid`: its children, theirs, and so on (a TUI's capture child, its reader process)."""
    out, todo = [], [pid]
    while todo:
        kids = children(todo.pop())
        out += kids
        todo += kids
    return out


def fds_on(pid: int, path: str) -> int:
    """How many descriptors process `pid` holds on `path` (who holds a port)."""
    n = 0
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            n += os.readlink(f"/proc/{pid}/fd/{fd}") == path
        except OSError:  # closed meanwhile
            pass
    return n
