"""In-band UART error marks (sniffer/sources/parmrk.py), and the settings a pty notes for a simulated line
(sniffer/sources/pty_settings.py), on real pseudo-terminals."""

from __future__ import annotations

import os
import select
import time
from contextlib import contextmanager

import pytest

from sniffer.line import LineSettings
from sniffer.sources.parmrk import ERROR, NUL_ERROR, InputFlags, MarkReader, tty_bytes
from sniffer.sources.pty_settings import read_settings
from sniffer.events import CaptureError
from sniffer.sources.serial_port import configure, open_read_only

CHARS = [(0x01, ""), (0xFF, ""), (0x41, "parity"), (0x00, "break"), (0x7E, "framing")]
MARKED = InputFlags(parmrk=True, inpck=True)


def test_tty_bytes_as_n_tty_hands_them_over():
    assert tty_bytes(CHARS, MARKED) == bytes.fromhex("01 ffff ff0041 ff0000 ff007e")
    assert tty_bytes(CHARS, InputFlags(inpck=True)) == bytes.fromhex("01 ff 00 00 00")  # INPCK alone: bad -> 00
    assert tty_bytes(CHARS, InputFlags()) == bytes.fromhex("01 ff 41 00 7e")  # as received
    assert tty_bytes(CHARS, InputFlags(parmrk=True, inpck=True, ignpar=True, ignbrk=True)) == bytes.fromhex("01ffff")


def test_mark_reader_unmarks_and_keeps_state_across_reads():
    raw = tty_bytes(CHARS, MARKED)
    want = (bytes.fromhex("01ff4100 7e"), [(2, ERROR), (3, NUL_ERROR), (4, ERROR)])
    assert MarkReader().feed(raw) == want
    for cut in range(1, len(raw)):  # a mark cut by a read
        r = MarkReader()
        a, ma = r.feed(raw[:cut])
        b, mb = r.feed(raw[cut:])
        assert (a + b, ma + [(o + len(a), k) for o, k in mb]) == want


@contextmanager
def opened(path: str, line: LineSettings, marks: bool = True):
    """(fd, what the driver ignored) of the port opened as detect opens it; closed after."""
    fd, _, ignored = open_read_only(path, line, marks=marks)
    try:
        yield fd, ignored
    finally:
        os.close(fd)


@pytest.fixture
def pty():
    master, slave = os.openpty()
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


@pytest.mark.parametrize("line", [LineSettings(19200, "E", 1), LineSettings(9600, "O", 2), LineSettings(1200, "N", 2),
                                  LineSettings(14400, "N", 1), LineSettings(921600, "E", 1, 7)], ids=LineSettings.label)
@pytest.mark.parametrize("marks", [True, False])
def test_a_pty_line_reads_back_the_settings_the_sniffer_set(pty, line, marks):
    master, path = pty
    with opened(path, line, marks) as (_, ignored):
        # the pty itself keeps no parity and always 8 bits: the note carries them
        assert ("char_format" in ignored) == (line.parity != "N" or line.databits == 7)
        got = read_settings(master)
    assert got.line == line
    assert got.flags == InputFlags(parmrk=marks, inpck=marks)


def _read(fd, n: int) -> bytes:
    got = b""
    deadline = time.monotonic() + 5
    while len(got) < n and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.1)[0]:
            got += os.read(fd, 100)
    return got


def test_marks_written_to_the_pty_arrive_unchanged(pty):
    master, path = pty
    with opened(path, LineSettings(19200, "E", 1)) as (fd, _):
        raw = tty_bytes(CHARS, read_settings(master).flags)
        os.write(master, raw)
        got = _read(fd, len(raw))
    assert got == raw  # PARMRK is off on the pty itself: its line discipline doubles no 0xFF
    assert MarkReader().feed(got)[1] == [(2, ERROR), (3, NUL_ERROR), (4, ERROR)]


def test_reconfigure_keeps_the_port_read_only(pty):
    master, path = pty
    with opened(path, LineSettings(9600, "N", 1)) as (fd, _):
        configure(fd, LineSettings(38400, "O", 1), pty=True, marks=True)
        assert read_settings(master).line == LineSettings(38400, "O", 1)
        with pytest.raises(OSError):
            os.write(fd, b"x")  # O_RDONLY: EBADF


def test_not_a_tty_is_one_line(tmp_path):
    f = tmp_path / "plain"
    f.write_bytes(b"")
    with pytest.raises(CaptureError, match="not a serial port"):
        open_read_only(str(f), LineSettings(), marks=True)
