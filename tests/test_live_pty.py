"""Live capture over a real pseudo-terminal pair, driven by the simulator.

Checks what arrived, not when (pty delivery jitter reaches milliseconds):
N frames sent -> N frames decoded with the same bytes, zero bytes written
to the port, and the MCAP written live replays to identical JSONL.
"""

from __future__ import annotations

import threading

from helpers import ListSink

from decoders.registry import default_registry
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.capture.session import CaptureSpec, Session
from sniffer.formats.mcap.sink import McapSink
from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.scenario import get_scenario
from sniffer.formats.mcap.reader import open_mcap, read_frames
from sniffer.sources.serial_live import SerialSource

LINE = LineSettings(19200, "E", 1)


def _live(tmp_path, scenario="default", seconds=2.0, speed=4.0):
    sent = list(simulate(get_scenario(scenario), LINE, seconds, seed=7))
    out = tmp_path / "live.mcap"
    collector = ListSink()
    stop = threading.Event()
    with PtyBus() as bus:
        source = SerialSource(bus.port, LINE, reconnect=False, low_latency=False)
        result = {}

        def play():
            result["stats"] = bus.play(sent, speed=speed, stop_event=stop)
            stop.wait(0.5)  # then let the capture see the line go quiet
            stop.set()

        session = Session(CaptureSpec(duration_s=30), source, [collector, McapSink(out)], stop=stop,
                          keep_partial=True)
        session.open()  # the port is open: now the bus may talk
        threading.Thread(target=play, daemon=True).start()
        session.run()
        bus.drain()
        written_back = bus.bytes_received_from_sniffer
    assert session.error is None
    return sent, collector, out, result["stats"], written_back


def test_n_frames_sent_n_decoded_nothing_written(tmp_path):
    sent, collector, out, stats, written_back = _live(tmp_path)
    assert stats.frames == len(sent) > 50 and not stats.stopped
    assert [r["raw"] for r in collector.records] == [f.raw.hex() for f in sent]
    assert all(r["crc_ok"] for r in collector.records)
    assert written_back == 0  # passive: not one byte went to the bus
    roles = [r["role"] for r in collector.records]
    assert roles.count("response") == sum(1 for f in sent if f.role == "response")


def test_live_mcap_replays_to_identical_jsonl(tmp_path):
    sent, collector, out, stats, _ = _live(tmp_path, scenario="errors", seconds=2.0)
    assert read_frames(str(out)) == collector.records  # frames logged live
    info, events = open_mcap(str(out))
    assert info.time_source == "read" and info.baud == LINE.baud
    replay = ListSink()
    p = Pipeline(info, LineSettings(info.baud, info.parity, info.stopbits), default_registry(), [replay])
    for ev in events:
        p.feed(ev)
    p.finish()
    assert replay.records == collector.records
