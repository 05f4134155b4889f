"""Several links captured at once over real pseudo-terminals (sources/serial_links.py, sniffer.capture.links).

Three simulated lines play on three ptys at the same time, each at its own settings; one session
captures them: every link's frames are exactly what was sent on it (no byte of one link glued onto
another's frames), nothing is written to any port, and the MCAP written live replays to the same
records, link by link.  A tapped 4-wire link: two ptys carry the master's and the slaves' pairs.
Checks what arrived, not when (pty delivery jitter reaches milliseconds).
"""

from __future__ import annotations

import errno
import fcntl
import os
import threading

import pytest
from helpers import ListSink

from sniffer.line import LineSettings
from sniffer.capture.session import CaptureSpec, Session
from sniffer.capture.settings import MASTER, SLAVES, LinkPlan
from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus, play_tap
from sniffer.simulator.scenario import get_scenario
from sniffer.formats.mcap.sink import McapSink
from sniffer.events import CaptureError
from sniffer.formats.mcap.reader import open_mcap, read_frames
from sniffer.sources.files import FileSource
from sniffer.sources.serial_links import LinksSource

LINES = {"drives": LineSettings(19200, "E", 1), "pumps": LineSettings(9600, "N", 2),
         "fans": LineSettings(38400, "N", 1)}


def _capture(tmp_path, buses, plans, play):
    """Run a LinksSource session over `plans` while `play(stop)` plays the buses: (session, sink, mcap)."""
    out = tmp_path / "links.mcap"
    sink = ListSink()
    stop = threading.Event()
    source = LinksSource(plans, reconnect=False, low_latency=False)
    session = Session(CaptureSpec(duration_s=60), source, [sink, McapSink(out)], stop=stop, keep_partial=True)
    session.open()  # every port open: now the lines may talk
    for r in source.readers:  # read-only, every one of them
        assert fcntl.fcntl(r.fd, fcntl.F_GETFL) & os.O_ACCMODE == os.O_RDONLY
        with pytest.raises(OSError) as e:
            os.write(r.fd, b"\x00")
        assert e.value.errno == errno.EBADF

    def run():
        play(stop)
        stop.wait(0.5)  # then let the capture see the lines go quiet
        stop.set()

    threading.Thread(target=run, daemon=True).start()
    session.run()
    for bus in buses:
        bus.drain()
    assert session.error is None
    return session, sink, out


def test_three_links_each_gets_exactly_its_frames_and_nothing_is_written(tmp_path):
    sent = {name: list(simulate(get_scenario("default"), line, 2.0, seed=i))
            for i, (name, line) in enumerate(LINES.items())}
    buses = {name: PtyBus() for name in LINES}
    try:
        plans = [(LinkPlan(name, (buses[name].port,)), line) for name, line in LINES.items()]
        stats = {}

        def play(stop):
            threads = [threading.Thread(target=lambda n=n: stats.__setitem__(n, buses[n].play(sent[n], 2.0, stop)))
                       for n in LINES]
            for t in threads:
                t.start()
            for t in threads:
                t.join()

        session, sink, out = _capture(tmp_path, buses.values(), plans, play)
        written_back = {n: b.bytes_received_from_sniffer for n, b in buses.items()}
    finally:
        for b in buses.values():
            b.close()
    assert written_back == {n: 0 for n in LINES}  # passive on every port
    for name in LINES:
        assert not stats[name].stopped
        got = [r for r in sink.records if r["link"] == name]
        assert [r["raw"] for r in got] == [f.raw.hex() for f in sent[name]]  # no glue, nothing lost
        assert all(r["crc_ok"] for r in got)
        assert sum(r["role"] == "response" and r["pair"] is not None for r in got) == \
            sum(f.role == "response" for f in sent[name])
    # one capture-wide numbering: every frame its own number, pairs within their link
    by_index = {r["index"]: r for r in sink.records}
    assert sorted(by_index) == list(range(len(sink.records)))
    assert all(by_index[r["pair"]]["link"] == r["link"] for r in sink.records if r["pair"] is not None)
    # each link ran at its own settings, recorded in the file
    info, events = open_mcap(str(out))
    assert [(x["name"], x["baud"], x["parity"], x["stopbits"]) for x in info.links] == \
        [(n, ln.baud, ln.parity, ln.stopbits) for n, ln in LINES.items()]
    assert {ev.link for ev in events} == set(LINES)  # every raw event says its link
    # the file replays to the same records, link by link (the live run's golden)
    assert read_frames(str(out)) == sink.records
    replay = ListSink()
    Session(CaptureSpec(), FileSource(str(out)), [replay]).run()
    assert replay.records == sink.records


def test_tap_two_ptys_carry_one_link_merged_by_time(tmp_path):
    line = LineSettings(19200, "E", 1)
    sent = list(simulate(get_scenario("default"), line, 2.0, seed=3))
    master, slaves = PtyBus(), PtyBus()
    try:
        plan = LinkPlan("tapped", (master.port, slaves.port), tap=True)
        stats = {}

        def play(stop):
            stats["m"], stats["s"] = play_tap(master, slaves, sent, speed=0.5, stop_event=stop)

        session, sink, out = _capture(tmp_path, (master, slaves), [(plan, line)], play)
        back = master.bytes_received_from_sniffer + slaves.bytes_received_from_sniffer
    finally:
        master.close()
        slaves.close()
    assert back == 0
    assert stats["m"].frames > 20 and stats["s"].frames > 20
    recs = sink.records
    requests = [f.raw.hex() for f in sent if f.role in ("request", "broadcast")]
    answers = [f.raw.hex() for f in sent if f.role not in ("request", "broadcast")]
    # each pair's bytes as sent, in order, on its own wire; the direction is the wire's
    assert [r["raw"] for r in recs if r["channel"] == MASTER] == requests
    assert [r["raw"] for r in recs if r["channel"] == SLAVES] == answers
    assert {r["role"] for r in recs if r["channel"] == MASTER} == {"request"}
    assert {r["role"] for r in recs if r["channel"] == SLAVES} == {"response"}
    # merged by time into one line: the answers find their requests (a scheduler hiccup of more than
    # the turnaround could swap a pair's reads; a tenth is far more than one hiccup)
    paired = sum(r["pair"] is not None for r in recs if r["channel"] == SLAVES)
    assert paired >= 0.9 * len(answers)
    assert all(recs[0]["link"] == r["link"] == "tapped" for r in recs)
    replay = ListSink()
    Session(CaptureSpec(), FileSource(str(out)), [replay]).run()
    assert replay.records == recs


def test_a_missing_second_port_opens_nothing(tmp_path):
    with PtyBus() as bus:
        line = LineSettings(19200, "E", 1)
        source = LinksSource([(LinkPlan("a", (bus.port,)), line),
                              (LinkPlan("b", (str(tmp_path / "ttyUSB9"),)), line)], low_latency=False)
        out = tmp_path / "x.mcap"
        session = Session(CaptureSpec(), source, [McapSink(out)], keep_partial=True)
        with pytest.raises(CaptureError, match="ttyUSB9: no such port"):
            session.open()
        assert all(r.fd is None for r in source.readers)  # the first port was closed again
        assert not any(t.name.startswith("serial-reader") for t in threading.enumerate())
