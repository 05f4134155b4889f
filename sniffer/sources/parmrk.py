"""UART errors marked in band by the tty (termios PARMRK + INPCK): how a reader unmarks them, how a line shows them.

With PARMRK and INPCK set (and IGNPAR, IGNBRK, ISTRIP clear), Linux's n_tty hands
the reader every received character as:

    a good byte c          c           (0xFF doubled: FF FF)
    a parity or framing    FF 00 c     (c as the UART received it; the tty
      error on byte c                   cannot say which of the two it was)
    a break                FF 00 00    (the same as an error on a 0x00 byte)

Without PARMRK, INPCK makes a bad byte read as a plain 0x00, and without INPCK
it reads as received: the marks are the only way a reader learns of an error.
`MarkReader` turns a marked stream back into bytes and error offsets (a mark may
be cut by a read: it keeps its state across `feed` calls); `tty_bytes` is the
other direction, what n_tty hands a reader for received characters with given
input flags (the simulator's pty line, sniffer/simulator/uartpty.py).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

ERROR = "error"  # a parity or framing error (PARMRK does not say which)
NUL_ERROR = "error-or-break"  # FF 00 00: a break, or an error on a 0x00 byte

_NORMAL, _FF, _FF00 = 0, 1, 2


class MarkReader:
    """Bytes read from a tty with PARMRK + INPCK -> (the bytes received, their error marks)."""

    def __init__(self) -> None:
        self._state = _NORMAL

    def feed(self, data: bytes) -> tuple[bytes, list[tuple[int, str]]]:
        """The received bytes in `data` and [(offset in them, ERROR or NUL_ERROR)]."""
        if self._state == _NORMAL and 0xFF not in data:
            return data, []  # the common case: nothing marked
        out = bytearray()
        marks: list[tuple[int, str]] = []
        state = self._state
        for b in data:
            if state == _NORMAL:
                if b == 0xFF:
                    state = _FF
                else:
                    out.append(b)
            elif state == _FF:
                if b == 0x00:
                    state = _FF00
                else:  # FF FF is a received 0xFF; FF then anything else cannot come from n_tty: keep both
                    out.append(0xFF)
                    if b != 0xFF:
                        out.append(b)
                    state = _NORMAL
            else:
                marks.append((len(out), NUL_ERROR if b == 0 else ERROR))
                out.append(b)
                state = _NORMAL
        self._state = state
        return bytes(out), marks


@dataclass(frozen=True, slots=True)
class InputFlags:
    """The input flags of a tty that decide how it hands over bad characters."""

    parmrk: bool = False
    inpck: bool = False
    ignpar: bool = False
    ignbrk: bool = False


def tty_bytes(chars: Iterable[tuple[int, str]], flags: InputFlags) -> bytes:
    """What n_tty hands a reader for received (value, error) characters; error is "" (good),
    "parity", "framing" or "break" (drivers/tty/n_tty.c, as the 8250 driver flags them)."""
    out = bytearray()
    for value, error in chars:
        if error == "break":
            if flags.ignbrk:
                continue
            out += b"\xff\x00\x00" if flags.parmrk else b"\x00"
        elif error and flags.inpck:
            if flags.ignpar:
                continue
            out += bytes((0xFF, 0x00, value)) if flags.parmrk else b"\x00"
        elif value == 0xFF and flags.parmrk:
            out += b"\xff\xff"
        else:
            out.append(value)
    return bytes(out)
