"""The serial settings of a pseudo-terminal: what it keeps, and the note that carries what it drops.

A simulated line on a pty (sniffer/simulator/uartpty.py) must deliver what a UART
at the sniffer's settings would receive, so it reads those settings back from its
end (tcgetattr on the master reads the slave's termios).  Linux keeps most of
them: the baud rate, PARODD, CSTOPB and the input flags.  But it drops two, and
cannot carry a third:

* PARENB and CSIZE: the pty driver clears PARENB and forces CS8 on every
  tcsetattr (drivers/tty/pty.c, pty_set_termios), so 8E1 reads back as 8N1;
* in-band error marks: with PARMRK on the slave, its line discipline doubles every
  0xFF the master writes (as it does a received 0xFF), so the master can never
  produce the FF 00 that marks an error (sniffer/sources/parmrk.py).

So on a pty, and only there (sniffer/sources/serial_port.py), the sniffer notes
the character format and the marks it asked for in c_cc[VSWTC], a control
character Linux's n_tty never reads, and leaves PARMRK itself off: the line
writes the marks as n_tty would have made them.  The note is one byte:

    0x80  a note is present (0: nobody noted anything; termios alone is read)
    0x01  PARENB (parity E or O; PARODD stays in c_cflag)
    0x02  7 data bits (CS7)
    0x04  PARMRK (errors marked in band)
"""

from __future__ import annotations

import array
import fcntl
import termios
from dataclasses import dataclass

from sniffer.line import LineSettings
from sniffer.sources.parmrk import InputFlags

NOTE = termios.VSWTC
_PRESENT, _PARENB, _CS7, _PARMRK = 0x80, 0x01, 0x02, 0x04
_SPEEDS = {getattr(termios, name): int(name[1:]) for name in dir(termios)
           if name.startswith("B") and name[1:].isdigit() and int(name[1:]) > 0}


def note_settings(cc: list, iflag: int, line: LineSettings, marks: bool) -> int:
    """Note `line`'s parity and data bits and `marks` in `cc` (a tcgetattr list, changed in place);
    the iflag to set: PARMRK off (the note carries it)."""
    cc[NOTE] = bytes((_PRESENT | (_PARENB if line.parity != "N" else 0) | (_CS7 if line.databits == 7 else 0)
                      | (_PARMRK if marks else 0),))
    return iflag & ~termios.PARMRK


@dataclass(frozen=True, slots=True)
class PortSettings:
    """What a UART set like the tty would receive with, and how its tty hands errors over."""

    line: LineSettings
    flags: InputFlags


def read_settings(fd: int) -> PortSettings:
    """The settings of the pty behind `fd` (either end), the note included (OSError / termios.error
    if it is gone)."""
    iflag, _, cflag, _, ispeed, _, cc = termios.tcgetattr(fd)
    note = cc[NOTE]
    note = note[0] if isinstance(note, bytes) else int(note)
    if not note & _PRESENT:  # nobody noted anything: termios alone (a pty says 8 bits, no parity)
        note = (_PARENB if cflag & termios.PARENB else 0) | (_CS7 if cflag & termios.CSIZE == termios.CS7 else 0)
        note |= _PARMRK if iflag & termios.PARMRK else 0
    parity = ("O" if cflag & termios.PARODD else "E") if note & _PARENB else "N"
    line = LineSettings(_baud(fd, ispeed), parity, 2 if cflag & termios.CSTOPB else 1, 7 if note & _CS7 else 8)
    flags = InputFlags(parmrk=bool(note & _PARMRK), inpck=bool(iflag & termios.INPCK),
                       ignpar=bool(iflag & termios.IGNPAR), ignbrk=bool(iflag & termios.IGNBRK))
    return PortSettings(line, flags)


def _baud(fd: int, ispeed: int) -> int:
    """The input baud rate: termios2's c_ispeed (any rate, BOTHER included), else the Bnnn constant."""
    try:
        from serial import serialposix

        buf = array.array("i", [0] * 64)
        fcntl.ioctl(fd, serialposix.TCGETS2, buf)
        if buf[9] > 0:
            return buf[9]
    except (ImportError, AttributeError, OSError):
        pass
    return _SPEEDS.get(ispeed, 9600)
