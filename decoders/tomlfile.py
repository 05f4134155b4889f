"""Read a TOML file (bus files, register maps) with one clear error line.

Refused, each as `error("<path>: <why>")`: a missing or unreadable file, a
directory, FIFO or device (reading one could block), a file over MAX_BYTES,
bytes that are not UTF-8, TOML that does not parse, nesting deep enough to
exhaust Python's recursion limit, numbers too long to convert.
"""

from __future__ import annotations

import os
import stat
import tomllib

MAX_BYTES = 16 << 20  # a bus file is a few lines, the largest register map ~200 kB


def read_text(path: str, error: type[Exception], what: str = "a bus file or register map",
              bom: bool = False) -> str:
    """A small text file (UTF-8; with `bom`, a byte-order mark allowed), or `error("<path>: <why>")`:
    never blocks on a FIFO, never reads more than MAX_BYTES of a device or a huge file."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise error(f"{path}: {e.strerror or e}") from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise error(f"{path}: is a directory, not a TOML file")
        if not stat.S_ISREG(mode):
            raise error(f"{path}: not a regular file (a FIFO or device?)")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as fh:
            data = fh.read(MAX_BYTES + 1)
    except OSError as e:
        raise error(f"{path}: {e.strerror or e}") from None
    finally:
        os.close(fd)
    if len(data) > MAX_BYTES:
        raise error(f"{path}: over {MAX_BYTES >> 20} MB: not {what}")
    try:
        return data.decode("utf-8-sig" if bom else "utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise error(f"{path}: not UTF-8 text (line {line}, byte {e.start})") from None


def read_toml(path: str, error: type[Exception]) -> dict:
    """The document, or `error("<path>: <why>")`."""
    text = read_text(path, error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML ({str(e)[:200]})") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply to be a bus file or register map") from None
    except ValueError as e:  # e.g. an integer over Python's digit limit
        raise error(f"{path}: not usable TOML ({str(e)[:200]})") from None
