"""Helper processes of a capture and the pipes between them (the publisher, the port's reader).

A message is a length-prefixed pickle (`pipe_message`); `read_messages` yields them until the
pipe ends, reading as much as the pipe holds at a time (one system call, and one wait for the
interpreter, for many messages).  `child_env` puts this sniffer package first on a child's path.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import struct
from collections.abc import Iterator

_LEN = struct.Struct("<I")
READ_BYTES = 1 << 16


def pipe_message(msg: tuple) -> bytes:
    """One message of a pipe: its length, then its pickle."""
    data = pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL)
    return _LEN.pack(len(data)) + data


def read_messages(fd: int) -> Iterator[tuple]:
    """The messages of a pipe, until EOF (a message cut by it is dropped)."""
    buf = b""
    at = 0
    while True:
        got = os.read(fd, READ_BYTES)
        if not got:
            return
        buf = buf[at:] + got if at < len(buf) else got
        at = 0
        while len(buf) - at >= _LEN.size:
            (n,) = _LEN.unpack_from(buf, at)
            if len(buf) - at - _LEN.size < n:
                break
            at += _LEN.size
            yield pickle.loads(buf[at:at + n])
            at += n


def write_all(fd: int, data: bytes) -> None:
    """All of `data` to a blocking pipe."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def pipe_size(fd: int, size: int) -> None:
    """Grow a pipe (Linux: F_SETPIPE_SZ) so a reader that is a moment behind does not block its writer."""
    import fcntl

    with contextlib.suppress(AttributeError, OSError):
        fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, size)


def child_env() -> dict:
    """The environment of a helper process: this sniffer package first on its path."""
    env = dict(os.environ)
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = here + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env
