"""A live capture's port is read by a process of its own (sniffer/processes/reader.py): a read's time
never waits for the capture's interpreter.

Real parts: a pty pair carries the bytes (PtyBus), the reader process is started as `sniffer live` starts it,
and the commands run on a terminal of their own.  Checked: what arrived, who holds the port, how the reader
process ends; never how fast.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

import pytest
from terminal import Terminal, children, fds_on, stat_fields

from sniffer.processes.pipes import read_messages
from sniffer.events import Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.scenario import get_scenario
from sniffer.events import CaptureError
from sniffer.formats.mcap.reader import read_frames
from sniffer.processes.reader import ReaderProcess, live_source
from sniffer.sources.serial_live import SerialSource

LINE = LineSettings(19200, "E", 1)
HANG_S = 60.0


def _gone(pid: int) -> bool:
    fields = stat_fields(pid)
    return fields is None or fields[0] == "Z"


def _collect(source, until, into: list) -> None:
    """Events of `source` into `into` until `until(into)` holds (then stop) or the source ends."""
    for ev in source.events():
        into.append(ev)
        if until(into):
            source.stop()


def _bytes(events) -> bytes:
    return b"".join(ev.data for ev in events if type(ev) is Chunk)


def test_the_port_is_read_by_a_process_of_its_own_and_nothing_is_written(tmp_path):
    """Every byte played arrives, in time order, read by a child process holding the port (this process never
    opens it); stop() ends the child; not one byte reaches the bus."""
    sent = list(simulate(get_scenario("default"), LINE, 1.0, seed=7))
    wire = b"".join(f.raw for f in sent)
    with PtyBus() as bus:
        src = ReaderProcess("serial", bus.port, LINE, low_latency=False, reconnect=False)
        info = src.open()
        child = src._proc.pid
        assert fds_on(child, bus.port)
        assert fds_on(os.getpid(), bus.port) == 1  # the bus's own end of the line; the capture's process opened none
        assert info.port == bus.port and info.baud == LINE.baud and info.time_source == "read"
        assert "reader" in info.extra  # the reader's priority, as the child's thread got it
        got: list = []
        t = threading.Thread(target=_collect, args=(src, lambda evs: len(_bytes(evs)) >= len(wire), got))
        t.start()
        stats = bus.play(sent, speed=4.0)
        t.join(HANG_S)
        assert not t.is_alive(), f"{len(_bytes(got))} of {len(wire)} bytes arrived"
        src.stop()
        assert _gone(child)
        bus.drain()
        assert bus.bytes_received_from_sniffer == 0
    assert stats.frames == len(sent) and _bytes(got) == wire
    times = [ev.t_ns for ev in got]
    assert times == sorted(times) and times[0] >= info.t0_ns
    assert any(type(ev) is Tick for ev in got)  # the silences between frames, as the reader thread says them


def test_a_missing_port_fails_as_the_reader_thread_does(tmp_path):
    port = str(tmp_path / "ttyNONE")
    with pytest.raises(CaptureError) as own:
        SerialSource(port, LINE).open()
    src = ReaderProcess("serial", port, LINE)
    with pytest.raises(CaptureError) as child:
        src.open()
    assert str(child.value) == str(own.value) and type(child.value) is type(own.value)
    assert src._proc.returncode is not None  # no child left behind


def test_a_reader_process_that_dies_ends_the_readers_with_one_error():
    with PtyBus() as bus:
        src = ReaderProcess("serial", bus.port, LINE, low_latency=False)
        src.open()
        os.kill(src._proc.pid, signal.SIGKILL)
        with pytest.raises(CaptureError, match="reader process ended .killed by SIGKILL"):
            for _ in src.events():
                pass
        src.stop()


def test_the_events_cross_the_pipe_whole():
    """What a reader pushes is what the capture gets: a read with every field (a stalled read's unseen_ns), a
    tick, a gap, a lost port and its return (for the status), each reader's end with its error."""
    from sniffer.processes.reader import PipeHub, ReaderEnd

    r, w = os.pipe()
    hub = PipeHub(w)
    chunk = Chunk(10, b"\x01\x03", None, ((1, "parity"),), "master", "a", 5_000_000)
    reader = SerialSource("/dev/ttyX", LINE, hub=hub)
    hub.push(chunk)
    hub.push(Tick(11, "a"))
    hub.push(Gap(12, 13, "port lost (hang-up), reopened", "a"))
    reader.lost_since_ns, reader.lost_reason = 14, "hang-up"
    hub.lost(reader)
    reader._error = CaptureError("/dev/ttyX: port lost (hang-up)")
    hub.push(ReaderEnd(reader))
    os.close(w)

    src = ReaderProcess("serial", "/dev/ttyX", LINE)
    got = []
    with pytest.raises(CaptureError, match="port lost"):
        for ev in src._events_from(read_messages(r)):
            got.append(ev)
    os.close(r)
    assert got == [chunk, Tick(11, "a"), Gap(12, 13, "port lost (hang-up), reopened", "a")]
    assert src.readers[0].lost_since_ns == 14 and src.readers[0].lost_reason == "hang-up"


def test_sniffer_reader_thread_keeps_the_reader_in_the_capture(monkeypatch):
    monkeypatch.setenv("SNIFFER_READER", "thread")
    assert type(live_source("serial", "/dev/ttyX", LINE)) is SerialSource
    monkeypatch.delenv("SNIFFER_READER")
    assert type(live_source("serial", "/dev/ttyX", LINE)) is ReaderProcess


def _live(port: str, out) -> Terminal:
    return Terminal([sys.executable, "-m", "sniffer", "live", port, "--baud", "19200", "--parity", "E",
                     "--headless", "--out", str(out)])


def _reader_of(term: Terminal, port: str) -> int:
    """The capture's reader process, once the capture says it captures: the port is configured and its input
    flushed then (bytes played before that are dropped, as the port's own, and the test would miss them)."""
    assert term.wait_for("(read-only)"), term.screen[-2000:]
    deadline = time.monotonic() + HANG_S
    while True:
        found = [p for p in children(term.proc.pid) if fds_on(p, port)]
        if found:
            return found[0]
        assert time.monotonic() < deadline, term.screen[-2000:]
        term.read(0.05)


def test_ctrl_c_on_the_terminal_stops_the_capture_not_its_reader(tmp_path):
    """Ctrl-C reaches the whole foreground group: the reader process ignores it, the capture stops as always
    (every frame recorded, a summary, exit 0), then its reader process ends."""
    sent = list(simulate(get_scenario("default"), LINE, 1.0, seed=7))
    out = tmp_path / "c.mcap"
    with PtyBus() as bus:
        term = _live(bus.port, out)
        reader = _reader_of(term, bus.port)
        assert not fds_on(term.proc.pid, bus.port)
        bus.play(sent, speed=4.0)
        time.sleep(0.3)
        os.killpg(term.proc.pid, signal.SIGINT)  # as the terminal's Ctrl-C does
        rc = term.finish()
        bus.drain()
        assert bus.bytes_received_from_sniffer == 0
    text = term.screen.decode(errors="replace")
    assert rc == 0 and "Traceback" not in text, text
    assert _gone(reader)
    assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in sent]


def test_a_killed_reader_process_costs_one_line_and_keeps_the_capture(tmp_path):
    """The reader process killed mid-capture: the capture says so in one line, exits non-zero, and its MCAP
    keeps every frame that came before."""
    sent = list(simulate(get_scenario("default"), LINE, 1.0, seed=7))
    out = tmp_path / "k.mcap"
    with PtyBus() as bus:
        term = _live(bus.port, out)
        reader = _reader_of(term, bus.port)
        bus.play(sent, speed=4.0)
        assert term.wait_for(f"#{len(sent) - 1} "), term.screen[-2000:]  # every frame through the reader
        os.kill(reader, signal.SIGKILL)
        rc = term.finish()
    text = term.screen.decode(errors="replace")
    errors = [ln for ln in text.splitlines() if "reader process ended" in ln]
    assert rc != 0 and "Traceback" not in text and len(errors) == 1, text
    assert "killed by SIGKILL" in errors[0]
    assert [r["raw"] for r in read_frames(str(out))] == [f.raw.hex() for f in sent]


def test_a_capture_killed_outright_ends_its_reader_process(tmp_path):
    """SIGKILL leaves the capture no say: its reader process sees the pipe end and closes the port."""
    with PtyBus() as bus:
        term = _live(bus.port, tmp_path / "x.mcap")
        reader = _reader_of(term, bus.port)
        os.kill(term.proc.pid, signal.SIGKILL)
        term.finish()
        deadline = time.monotonic() + HANG_S
        while not _gone(reader):
            assert time.monotonic() < deadline, "the reader process outlived its capture"
            time.sleep(0.05)


def test_several_links_one_port_missing_fails_on_that_port(tmp_path):
    """Several links in one reader process: the first port opens (its reader starts, and stops again), the
    second is missing; the capture gets the missing port's own error, as the reader threads raised it."""
    from sniffer.capture.settings import LinkPlan

    missing = str(tmp_path / "ttyNONE")
    with PtyBus() as bus:
        plans = [(LinkPlan("a", (bus.port,)), LINE), (LinkPlan("b", (missing,)), LINE)]
        os.write(bus.master_fd, b"\x01\x03\x00\x00")  # the first port's reader has bytes to say
        src = ReaderProcess("links", plans, low_latency=False)
        with pytest.raises(CaptureError) as e:
            src.open()
        assert missing in str(e.value) and src._proc.returncode is not None
        assert fds_on(os.getpid(), bus.port) == 1
