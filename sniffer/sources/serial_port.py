"""Opening a serial port read-only and setting its line: the one place that touches a port's termios.

`sniffer live` (serial_live.SerialSource) and `sniffer detect` (sniffer/detect/listen.py)
both open the port here, and only here:

* os.open(O_RDONLY | O_NOCTTY | O_NONBLOCK), never pyserial's Serial (its open()
  uses O_RDWR, then drives DTR/RTS and flushes buffers).  A write on this fd
  fails with EBADF;
* raw mode with everything off with which a tty could transmit on its own
  (ECHO echoes received bytes back out, IXOFF sends XOFF when the input buffer
  fills); `configure` reads the settings back and refuses to go on if they did
  not stick;
* with `marks`, the tty reports UART errors in band (PARMRK + INPCK, see
  sniffer/sources/parmrk.py): what `detect` needs to tell a wrong parity or baud from a
  right one.  `live` reads bytes as received, unmarked.

A pseudo-terminal keeps no parity or character size (its driver forces CS8 and
clears PARENB) and its line discipline cannot carry marks from the other end
(it doubles every 0xFF written to it under PARMRK): on a pty the settings a
UART would have are noted for a simulated line instead (sniffer/sources/pty_settings.py).
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
import termios

from sniffer.line import LineSettings
from sniffer.sources.pty_settings import note_settings
from sniffer.events import CaptureError

# IGNPAR/IGNBRK would make UART drivers drop bad bytes, and bad bytes are what a sniffer is for.
# INPCK off delivers them as received; with `marks`, INPCK + PARMRK mark them in band.
_IFLAG_OFF = (termios.IGNBRK | termios.IGNPAR | termios.BRKINT | termios.PARMRK | termios.ISTRIP | termios.INLCR
              | termios.IGNCR | termios.ICRNL | termios.IXON | termios.IXOFF | termios.IXANY
              | termios.INPCK | termios.IMAXBEL | getattr(termios, "IUCLC", 0))
_MARKS = termios.PARMRK | termios.INPCK
# ECHO* would transmit received bytes back: these are the flags that must never stay on.
_LFLAG_OFF = (termios.ECHO | termios.ECHOE | termios.ECHOK | termios.ECHONL | termios.ICANON
              | termios.ISIG | termios.IEXTEN | getattr(termios, "ECHOCTL", 0) | getattr(termios, "ECHOKE", 0))
_MUST_BE_OFF = termios.ECHO | termios.ECHONL | termios.ICANON
_FRAME_BITS = termios.CSIZE | termios.PARENB | termios.PARODD | termios.CSTOPB
PTY_SLAVE_MAJORS = range(136, 144)  # UNIX98_PTY_SLAVE_MAJOR .. + UNIX98_PTY_MAJOR_COUNT


def is_pty(rdev: int) -> bool:
    return os.major(rdev) in PTY_SLAVE_MAJORS


def open_read_only(port: str, line: LineSettings, *, marks: bool = False) -> tuple[int, int, dict]:
    """(fd, st_rdev, what the driver ignored) of `port` opened read-only and set to `line`;
    CaptureError("<port>: <why>") otherwise, with nothing left open."""
    try:
        fd = os.open(port, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as e:
        raise CaptureError(f"{port}: {_open_error(e)}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISCHR(st.st_mode) or not os.isatty(fd):
            raise CaptureError("not a serial port (not a tty)")
        ignored = configure(fd, line, pty=is_pty(st.st_rdev), marks=marks)
    except CaptureError as e:
        os.close(fd)
        raise CaptureError(f"{port}: {e}") from None
    except BaseException:
        os.close(fd)
        raise
    return fd, st.st_rdev, ignored


def _open_error(e: OSError) -> str:
    if e.errno == errno.ENOENT:
        return "no such port (adapter unplugged or wrong name?)"
    if e.errno in (errno.EACCES, errno.EPERM):
        return "permission denied (is your user in the dialout group?)"
    if e.errno == errno.EBUSY:
        return "port is busy (another program holds it exclusively)"
    if e.errno in (errno.ENXIO, errno.ENODEV):
        return "no device behind this port"
    return e.strerror or str(e)


def configure(fd: int, line: LineSettings, *, pty: bool, marks: bool = False) -> dict:
    """Raw receive at the line's settings, no flow control; the read-back is the judge.

    Returns what the driver ignored and why that is acceptable (empty on a UART).
    Bytes received before (at other settings) are dropped.
    """
    try:
        iflag, oflag, cflag, lflag, _, _, cc = termios.tcgetattr(fd)
    except termios.error as e:
        raise CaptureError(f"not a serial port ({_termios_text(e)})") from None
    iflag &= ~_IFLAG_OFF
    if marks:
        iflag |= _MARKS
    oflag &= ~termios.OPOST
    lflag &= ~_LFLAG_OFF
    cflag &= ~(termios.CSIZE | termios.PARENB | termios.PARODD | termios.CSTOPB | termios.CRTSCTS)
    cflag |= termios.CLOCAL | termios.CREAD
    cflag |= termios.CS8 if line.databits == 8 else termios.CS7
    if line.parity != "N":
        cflag |= termios.PARENB | (termios.PARODD if line.parity == "O" else 0)
    if line.stopbits == 2:
        cflag |= termios.CSTOPB
    # The fd is O_NONBLOCK and waits in select(); VMIN=1/VTIME=0 makes select() wake on the first byte.
    cc[termios.VMIN] = 1
    cc[termios.VTIME] = 0
    if pty:
        iflag = note_settings(cc, iflag, line, marks)
    speed = getattr(termios, f"B{line.baud}", None)
    try:
        termios.tcsetattr(fd, termios.TCSANOW,
                          [iflag, oflag, cflag, lflag, speed or termios.B38400, speed or termios.B38400, cc])
    except termios.error:
        # glibc answers EINVAL after the ioctl succeeded when the driver dropped PARENB/CSIZE
        # (a pty does); whatever it was, the read-back below decides.
        pass
    try:
        if speed is None:
            _set_custom_baud(fd, line.baud)
        got_i, _, got_c, got_l, got_is, got_os, _ = termios.tcgetattr(fd)
    except (termios.error, OSError) as e:
        raise CaptureError(f"cannot configure the port: {_termios_text(e)}") from None
    if got_i & termios.IXOFF or got_l & _MUST_BE_OFF:
        raise CaptureError("the port kept echo or XOFF on; refusing to capture (it could transmit)")
    if speed is not None and (got_is, got_os) != (speed, speed):
        raise CaptureError(f"the driver refused {line.baud} baud")
    if got_i & _MARKS != iflag & _MARKS:
        raise CaptureError("the driver refused to mark parity and framing errors (PARMRK, INPCK)")
    ignored = {}
    want = cflag & _FRAME_BITS
    if got_c & _FRAME_BITS != want:
        if not pty:
            raise CaptureError(f"the driver refused the character format {line.databits}{line.parity}{line.stopbits}")
        ignored["char_format"] = "a pseudo-terminal has no line: parity/stop bits do not apply"
    # Bytes that arrived before raw mode (or at other settings) have no usable time and may be mangled:
    # drop them (TCIFLUSH discards input only; nothing is sent).
    termios.tcflush(fd, termios.TCIFLUSH)
    return ignored


def _set_custom_baud(fd: int, baud: int) -> None:
    """Non-standard rates (e.g. 250000) through termios2/BOTHER, as pyserial does."""
    import array

    from serial import serialposix

    buf = array.array("i", [0] * 64)
    fcntl.ioctl(fd, serialposix.TCGETS2, buf)
    buf[2] = (buf[2] & ~termios.CBAUD) | serialposix.BOTHER
    buf[9] = buf[10] = baud
    fcntl.ioctl(fd, serialposix.TCSETS2, buf)


def _termios_text(e: Exception) -> str:
    args = getattr(e, "args", ())
    if len(args) == 2 and isinstance(args[1], str):
        return args[1]
    return getattr(e, "strerror", None) or str(e)
