"""The live serial path over a real pseudo-terminal pair (no mocked serial).

The test plays the bus on the pty master; the sniffer opens the slave path.
Assertions are about what arrived, never when: pty delivery jitter on a
shared machine reaches milliseconds.  Every wait has a deadline.
"""

from __future__ import annotations

import errno
import fcntl
import os
import select
import threading
import time
import types

import pytest

from sniffer.events import Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.sources.lowlatency import request_low_latency
from sniffer.events import CaptureError
from sniffer.sources.serial_live import PortLostError, SerialSource

pytestmark = pytest.mark.timeout(15)  # a hang fails fast instead of stalling the suite

LINE = LineSettings(19200, "E", 1)
WAIT_S = 3.0


class Pty:
    """A pty pair; the test keeps its own slave fd open so the master never reads EIO."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        self.path = os.ttyname(self.slave)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


@pytest.fixture
def pty():
    p = Pty()
    yield p
    p.close()


@pytest.fixture
def started():
    sources = []

    def start(*args, **kw) -> SerialSource:
        src = SerialSource(*args, **kw)
        src.open()
        sources.append(src)
        return src

    yield start
    for s in sources:
        s.stop()


def collect(events, until, timeout=WAIT_S) -> list:
    """Pull events until `until(seen)` holds; fail (not hang) after `timeout`."""
    seen: list = []
    deadline = time.monotonic() + timeout
    for ev in events:
        seen.append(ev)
        if until(seen):
            return seen
        if time.monotonic() > deadline:
            break
    raise AssertionError(f"condition not met within {timeout} s; got {_summary(seen)}")


def data_of(seen) -> bytes:
    return b"".join(e.data for e in seen if type(e) is Chunk)


def _summary(seen) -> str:
    kinds = {}
    for e in seen:
        kinds[type(e).__name__] = kinds.get(type(e).__name__, 0) + 1
    return f"{kinds}, data={data_of(seen)!r}"


def test_bytes_arrive_as_chunks_in_order(pty, started):
    src = started(pty.path, LINE)
    ev = src.events()
    sent = b""
    for k in range(20):
        frame = bytes([1, 3, k, 0, 0, 2, 0xC4, k])
        os.write(pty.master, frame)
        sent += frame
    seen = collect(ev, lambda s: len(data_of(s)) >= len(sent))
    assert data_of(seen) == sent
    chunks = [e for e in seen if type(e) is Chunk]
    assert all(c.byte_t_ns is None and c.channel == "" and c.data for c in chunks)
    times = [e.t_ns for e in seen]
    assert times == sorted(times)  # one producer: the stream is in time order


def test_capture_info(pty, started):
    before = time.monotonic_ns()
    src = started(pty.path, LINE)
    info = src.info
    assert info.source == f"serial:{pty.path}" and info.port == pty.path
    assert (info.baud, info.parity, info.stopbits, info.databits) == (19200, "E", 1, 8)
    assert info.time_source == "read"
    assert before <= info.t0_ns <= time.monotonic_ns()
    assert abs(info.wall_anchor_ns - time.time_ns()) < 60 * 10**9
    assert src.open() is info  # idempotent


def test_passive_never_writes(pty, started):
    src = started(pty.path, LineSettings(9600, "N", 2))
    fd = src.fd
    assert fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE == os.O_RDONLY
    with pytest.raises(OSError) as e:
        os.write(fd, b"\x01")
    assert e.value.errno == errno.EBADF
    assert not hasattr(src, "write")
    # Traffic that a cooked tty would echo back (CR, ^S/^Q, a full line) must not come back.
    payload = b"\x01\x03\x00\x00\x00\x01\x84\x0a\r\n\x11\x13\x03\x1a" + bytes(range(256))
    os.write(pty.master, payload)
    seen = collect(src.events(), lambda s: len(data_of(s)) >= len(payload))
    assert data_of(seen) == payload
    src.stop()
    os.set_blocking(pty.master, False)
    with pytest.raises(BlockingIOError):
        os.read(pty.master, 1024)


def test_ticks_during_silence(pty, started):
    src = started(pty.path, LINE, tick_interval_s=0.005)
    ev = src.events()
    seen = collect(ev, lambda s: sum(type(e) is Tick for e in s) >= 5)
    ticks = [e.t_ns for e in seen if type(e) is Tick]
    assert ticks == sorted(ticks) and len(set(ticks)) == len(ticks)
    os.write(pty.master, b"\x05\x06")
    seen = collect(ev, lambda s: data_of(s) == b"\x05\x06" and type(s[-1]) is Tick)
    chunk_t = max(e.t_ns for e in seen if type(e) is Chunk)
    assert seen[-1].t_ns >= chunk_t  # the tick after the data says "silent since"


def test_a_tick_never_claims_silence_the_reader_did_not_see(pty, started, monkeypatch):
    """The reader's select gives up, then the thread stalls (its CPU or the interpreter taken) while the rest
    of a frame comes: the time it takes after the stall must not become a tick, or the framer, seeing
    silence past t3.5 + the read slack, cuts the frame in two."""
    from sniffer.framing.rtu import RtuFramer
    from sniffer.sources import serial_live

    real = select.select
    armed = threading.Event()
    req = bytes.fromhex("010300000002c40b")

    def stalling_select(r, w, x, timeout=None):
        ready = real(r, w, x, timeout)
        if armed.is_set() and timeout and not ready[0]:  # gave up: now the stall, and the bytes come in it
            armed.clear()
            os.write(pty.master, req[3:])
            time.sleep(0.08)
        return ready

    monkeypatch.setattr(serial_live, "select", types.SimpleNamespace(select=stalling_select))
    src = started(pty.path, LINE, tick_interval_s=0.005)
    ev = src.events()
    os.write(pty.master, req[:3])
    seen = collect(ev, lambda s: data_of(s) == req[:3])
    armed.set()
    seen += collect(ev, lambda s: data_of(s) == req[3:])
    first = next(i for i, e in enumerate(seen) if type(e) is Chunk)
    assert not any(type(e) is Tick for e in seen[first:])  # nothing between the two halves
    assert seen[-1].unseen_ns >= 80_000_000  # the rest came while the reader did not look
    framer = RtuFramer(LINE)
    out = [f for e in seen if type(e) is Chunk for f in framer.feed(e)] + framer.flush()
    assert [(f.raw, f.crc_ok) for f in out] == [(req, True)]


def test_stop_ends_events_and_joins(pty, started):
    src = started(pty.path, LINE)
    os.write(pty.master, b"\xaa")
    ev = src.events()
    collect(ev, lambda s: data_of(s) == b"\xaa")
    src.stop()
    rest = []
    deadline = time.monotonic() + WAIT_S
    for e in ev:  # drains what was queued, then ends
        rest.append(e)
        assert time.monotonic() < deadline
    assert not src._thread.is_alive()
    assert src.fd is None
    assert list(src.events()) == []  # a second iteration ends at once
    src.stop()  # idempotent


def test_stop_from_another_thread_ends_a_waiting_consumer(pty, started):
    src = started(pty.path, LINE, tick_interval_s=60)  # no ticks: the consumer really waits
    timer = threading.Timer(0.2, src.stop)
    timer.start()
    try:
        assert list(src.events()) == []
    finally:
        timer.join(WAIT_S)
    assert not src._thread.is_alive()


def test_unplug_and_replug(tmp_path, started):
    link = tmp_path / "ttyRS485"
    first = Pty()
    link.symlink_to(first.path)
    src = started(str(link), LINE)
    ev = src.events()
    os.write(first.master, b"before")
    collect(ev, lambda s: data_of(s) == b"before")

    # Unplug: the device node goes away and the slave side sees EIO.
    link.unlink()
    first.close()
    deadline = time.monotonic() + WAIT_S
    while src.lost_since_ns is None:  # ticks stop while the port is away, so poll the flag
        assert time.monotonic() < deadline, "loss not noticed"
        time.sleep(0.01)
    assert src.fd is None

    second = Pty()
    try:
        link.symlink_to(second.path)
        seen = collect(ev, lambda s: any(type(e) is Gap for e in s))
        gap = seen[-1]
        assert gap.t_ns < gap.t_end_ns and "port lost" in gap.reason
        os.write(second.master, b"after")
        seen = collect(ev, lambda s: data_of(s) == b"after")
        assert not any(type(e) is Gap for e in seen)  # one Gap per outage
        assert all(e.t_ns >= gap.t_end_ns for e in seen)
        src.stop()
        os.set_blocking(second.master, False)
        with pytest.raises(BlockingIOError):
            os.read(second.master, 64)
    finally:
        second.close()


def test_unplug_without_reconnect_raises(pty, started):
    src = started(pty.path, LINE, reconnect=False)
    ev = src.events()
    os.close(pty.master)
    with pytest.raises(PortLostError, match=pty.path):
        collect(ev, lambda s: False)


def test_stop_during_outage_records_the_gap(tmp_path, started):
    link = tmp_path / "port"
    p = Pty()
    link.symlink_to(p.path)
    src = started(str(link), LINE)
    link.unlink()
    p.close()
    deadline = time.monotonic() + WAIT_S
    while src.lost_since_ns is None:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    src.stop()
    gaps = [e for e in src.events() if type(e) is Gap]
    assert len(gaps) == 1 and "stopped before it returned" in gaps[0].reason


@pytest.mark.parametrize("make", ["missing", "regular", "directory"])
def test_open_errors_are_one_line(tmp_path, make):
    path = tmp_path / "ttyNope"
    if make == "regular":
        path.write_bytes(b"")
    elif make == "directory":
        path.mkdir()
    with pytest.raises(CaptureError) as e:
        SerialSource(str(path), LINE).open()
    msg = str(e.value)
    assert msg.startswith(f"{path}: ") and "\n" not in msg
    assert ("no such port" in msg) if make == "missing" else ("not a serial port" in msg)


def test_nonstandard_baud_opens(pty, started):
    src = started(pty.path, LineSettings(250000, "O", 1))
    os.write(pty.master, b"\x10\x20")
    assert data_of(collect(src.events(), lambda s: data_of(s) == b"\x10\x20")) == b"\x10\x20"


def test_low_latency_on_pty_is_recorded_as_not_taken(pty, started, tmp_path):
    src = started(pty.path, LINE, sysfs=str(tmp_path))
    ll = src.info.low_latency
    assert ll["requested"] is True and ll["took_effect"] is False
    assert ll["async_low_latency"] is False and "TIOCGSERIAL" in ll["reason"]
    assert ll["latency_timer"]["took_effect"] is False and "not an FTDI" in ll["latency_timer"]["reason"]
    off = started(pty.path, LINE, low_latency=False)
    assert off.info.low_latency == {"requested": False}


def fake_ftdi_sysfs(root, name="ttyUSB7", value="16"):
    """What ftdi_sio exposes for a port; the only faked part (no adapter on this machine)."""
    d = root / "bus" / "usb-serial" / "devices" / name
    d.mkdir(parents=True)
    (d / "latency_timer").write_text(f"{value}\n")
    return d / "latency_timer"


def test_ftdi_latency_timer_set_to_1(pty, tmp_path):
    timer = fake_ftdi_sysfs(tmp_path / "sys")
    ll = request_low_latency(pty.slave, str(tmp_path / "dev" / "ttyUSB7"), sysfs=str(tmp_path / "sys"))
    lt = ll["latency_timer"]
    assert (lt["requested"], lt["before"], lt["after"], lt["took_effect"]) == (1, 16, 1, True)
    assert lt["path"] == str(timer) and "reason" not in lt
    assert timer.read_text().strip() == "1"
    assert ll["took_effect"] is True and ll["async_low_latency"] is False  # a pty has no serial_struct


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write a read-only file")
def test_ftdi_latency_timer_without_permission(pty, tmp_path):
    timer = fake_ftdi_sysfs(tmp_path / "sys")
    timer.chmod(0o444)
    lt = request_low_latency(pty.slave, str(tmp_path / "ttyUSB7"), sysfs=str(tmp_path / "sys"))["latency_timer"]
    assert (lt["before"], lt["after"], lt["took_effect"]) == (16, None, False)
    assert "udev" in lt["reason"]
