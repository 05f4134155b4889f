"""Files: only regular ones are opened, and no read is unbounded.

A FIFO would block open() or read() for ever, a character device (/dev/zero) never ends, a directory is
no file: each is refused in one line before a byte is read.  A reader that takes a whole file takes at
most the cap of its kind (CAPS) and names it when the file is bigger; a reader that streams lines caps
the length of a line.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from typing import BinaryIO

from sniffer.inputs.errors import InputError

# the most a reader of each kind takes whole (bytes): far above a real one, far below what hurts
CAPS = {
    "a bus file or register map": 16 << 20,  # a bus file is a few lines, the largest register map ~200 kB
    "a status file": 16 << 20,  # a capture's status file is a few kB
    "a parameter set": 64 << 20,  # --params CSV: a drive's parameters, a few hundred rows
    "a golden line": 1 << 20,  # a golden is streamed; one frame's line is under 1 kB
}

_KINDS = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISBLK, "a block device"))


def not_regular(path: str, mode: int, what: str = "a capture file") -> str | None:
    """Why a file of this st_mode cannot be read as `what`, or None for a regular file."""
    if stat.S_ISDIR(mode):
        return f"{path}: is a directory, not {what}"
    if stat.S_ISREG(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), "a special file")
    return f"{path}: not a regular file ({kind}): reading it would block forever or never end"


def open_regular(path: str | os.PathLike[str], what: str = "a capture file", error: type[Exception] = InputError
                 ) -> BinaryIO:
    """Open a file for binary reading, refusing anything but a regular file (`error`, one line).

    O_NONBLOCK keeps open() itself from waiting for a FIFO's writer; the
    file is then checked with fstat before a single byte is read.
    """
    p = os.fspath(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
                     | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise error(f"{p}: {e.strerror or e}") from None
    try:
        why = not_regular(p, os.fstat(fd).st_mode, what)
        if why is None and hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
    except OSError as e:
        os.close(fd)
        raise error(f"{p}: {e.strerror or e}") from None
    if why is not None:
        os.close(fd)
        raise error(why)
    return os.fdopen(fd, "rb")


def _mb(n: int) -> str:
    return f"{n >> 20} MB" if n >= 1 << 20 else f"{n >> 10} kB"


def read_capped(path: str, cap: int, what: str, error: type[Exception] = InputError) -> bytes:
    """The whole of a regular file of at most `cap` bytes, or `error("<path>: <why>")` naming the cap."""
    try:
        with open_regular(path, what, error) as fh:
            data = fh.read(cap + 1)
    except OSError as e:
        raise error(f"{path}: {e.strerror or e}") from None
    if len(data) > cap:
        raise error(f"{path}: over {_mb(cap)}: not {what}")
    return data


def read_text(path: str, cap: int, what: str, error: type[Exception] = InputError, bom: bool = False) -> str:
    """read_capped as UTF-8 text (with `bom`, a byte-order mark allowed)."""
    data = read_capped(path, cap, what, error)
    try:
        return data.decode("utf-8-sig" if bom else "utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise error(f"{path}: not UTF-8 text (line {line}, byte {e.start})") from None


def read_lines(path: str, what: str, line_cap: int = CAPS["a golden line"],
               error: type[Exception] = InputError) -> Iterator[str]:
    """A regular file's lines (without their newline; bad UTF-8 replaced), streamed: memory stays flat, and a
    line over `line_cap` bytes (a file that is no text, or a device's endless zeros) is refused."""
    with open_regular(path, what, error) as fh:
        for n, raw in enumerate(iter(lambda: fh.readline(line_cap + 1), b""), 1):
            if len(raw) > line_cap:
                raise error(f"{path}: line {n} is over {_mb(line_cap)}: not {what}")
            yield raw.decode("utf-8", "replace").rstrip("\n")
