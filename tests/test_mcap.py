"""MCAP sink / source / repair on real files: written, cut, killed, filled, read back."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import time

import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer

from sniffer.codes import CRC_MISMATCH, note
from sniffer.events import FLAG_FRAMING, FLAG_PARITY, CaptureInfo, Chunk, Gap, Tick
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings
from sniffer.formats.mcap.repair import default_output, repair
from sniffer.formats.mcap.format import RAW_SCHEMA, info_to_metadata
from sniffer.formats.mcap.sink import CaptureStorageError, McapSink
from sniffer.formats.records import FRAME_SCHEMA, frame_record, loads
from sniffer.events import CaptureError
from sniffer.formats.mcap.reader import McapSource, open_mcap, read_frames, sniff

TESTS = os.path.dirname(os.path.abspath(__file__))
T0 = 7_000_000_000
ANCHOR = 1_700_000_000_000_000_000
INFO = CaptureInfo(
    source="serial", port="/dev/ttyUSB0", baud=19200, parity="E", stopbits=1, time_source="read",
    t0_ns=T0, wall_anchor_ns=ANCHOR, low_latency={"requested": True, "ok": False},
    devices={1: "teco_a510", 17: "pd_series"}, sniffer_version="0.1.0",
)


def make_event(i: int) -> Chunk | Tick | Gap:
    """Deterministic event sequence shared with the child processes below."""
    t = T0 + i * 1_000_000
    k = i % 4
    if k == 0:
        data = bytes((i + j) & 0xFF for j in range(8))
        return Chunk(t, data, tuple(t + j * 573_000 for j in range(8)))
    if k == 1:
        flags = ((1, FLAG_PARITY),) if i % 3 == 0 else ()
        return Chunk(t, bytes([i & 0xFF, 0x03]), None, flags, "B")
    if k == 2:
        return Tick(t)
    return Gap(t, t + 500_000, f"adapter lost #{i}")


def write_capture(path, events, frames=(), info=INFO, **kw) -> None:
    sink = McapSink(path, **kw)
    sink.start(info)
    for ev in events:
        sink.raw(ev)
    for f in frames:
        sink.frame(f)
    sink.close()


def real_frames():
    """Frames from the real framer (one good request, one noise run), with decoder-style extras."""
    fr = RtuFramer(LineSettings(19200, "E"))
    req = bytes.fromhex("010300000002c40b")
    t = T0 + 1_000_000
    frames = fr.feed(Chunk(t, req, tuple(t + j * 573_000 for j in range(len(req)))))
    frames += fr.feed(Chunk(T0 + 60_000_000, bytes.fromhex("0103040001000263f2ff"), None, ((2, FLAG_FRAMING),)))
    frames += fr.flush()
    assert len(frames) >= 2
    frames[0].points = [{"name": "freq", "address": 0, "raw": 600, "value": 60.0, "unit": "Hz"}]
    frames[0].latency_ms = 12.3456
    frames[1].annotations.append(note(CRC_MISMATCH, "expected 1234", 0, 2))
    return frames


def messages(path):
    with open(path, "rb") as fh:
        return [(s, c, m) for s, c, m in make_reader(fh).iter_messages(log_time_order=False)]


# -- round trips -----------------------------------------------------------------------


def test_events_and_info_round_trip(tmp_path):
    p = tmp_path / "cap.mcap"
    events = [make_event(i) for i in range(40)]
    write_capture(p, events)
    info, it = open_mcap(p)
    assert info == INFO  # finished file: no "mcap_unfinished" mark
    assert list(it) == events
    assert sniff(p)

    with open(p, "rb") as fh:  # the default (seeking) reader opens a finished file
        reader = make_reader(fh)
        meta, fox = list(reader.iter_metadata())
    assert (meta.name, fox.name) == ("sniffer.capture", "foxglove")
    assert {k: json.loads(v) for k, v in meta.metadata.items()} == INFO.to_dict()

    msgs = messages(p)
    topics = [c.topic for _, c, _ in msgs]
    assert topics[0] == "/capture" and topics.count("/raw") == 40
    schema, chan, msg = msgs[1]
    assert (schema.name, schema.encoding, chan.message_encoding) == ("sniffer.RawEvent", "jsonschema", "json")
    assert json.loads(schema.data) == RAW_SCHEMA
    assert msg.log_time == msg.publish_time == ANCHOR + (events[0].t_ns - T0)
    assert loads(msg.data)["byte_dt_ns"] == [j * 573_000 for j in range(8)]


def test_frames_round_trip(tmp_path):
    p = tmp_path / "frames.mcap"
    frames = real_frames()
    write_capture(p, [make_event(0)], frames)
    assert read_frames(p) == [frame_record(f, T0) for f in frames]
    fmsgs = [(s, c, m) for s, c, m in messages(p) if c.topic == "/frames"]
    schema, chan, msg = fmsgs[0]
    assert (schema.name, schema.encoding, chan.message_encoding) == ("sniffer.Frame", "jsonschema", "json")
    assert json.loads(schema.data) == FRAME_SCHEMA
    assert [m.log_time for _, _, m in fmsgs] == [ANCHOR + f.t_ns - T0 for f in frames]
    assert [m.sequence for _, _, m in fmsgs] == list(range(len(frames)))


def test_log_time_is_clamped_at_zero(tmp_path):
    p = tmp_path / "clamp.mcap"
    info = CaptureInfo(baud=9600, parity="N", t0_ns=5_000, wall_anchor_ns=0)
    events = [Chunk(1_000, b"\x01"), Tick(9_000)]
    write_capture(p, events, info=info)
    assert [m.log_time for _, c, m in messages(p) if c.topic == "/raw"] == [0, 4_000]
    assert list(open_mcap(p)[1]) == events


# -- flushing ------------------------------------------------------------------------------


class FakeClock:
    def __init__(self) -> None:
        self.now = 0

    def __call__(self) -> int:
        return self.now


def test_flush_follows_the_sink_clock(tmp_path):
    p = tmp_path / "live.mcap"
    clock = FakeClock()
    sink = McapSink(p, flush_interval_s=1.0, clock=clock)
    sink.start(INFO)  # capture info goes to disk at once
    events = [make_event(i) for i in range(8)]

    def on_disk():
        info, it = open_mcap(p)
        assert info.baud == 19200 and info.extra["mcap_unfinished"] is True
        return list(it)

    for ev in events[:5]:
        sink.raw(ev)
    clock.now = 999_999_999
    sink.raw(events[5])
    assert on_disk() == []
    clock.now = 1_000_000_000
    sink.raw(events[6])
    assert on_disk() == events[:7]
    sink.raw(events[7])
    sink.maybe_flush()
    assert on_disk() == events[:7]
    clock.now = 2_000_000_000
    sink.maybe_flush()
    assert on_disk() == events
    sink.close()
    sink.close()  # twice is fine
    with pytest.raises(RuntimeError):
        sink.raw(events[0])
    assert list(open_mcap(p)[1]) == events


# -- bad files ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "content, words",
    [
        (b"", "empty file"),
        (b"t_s,channel,byte_hex,flags\n0.1,A,01,\n", "not an MCAP"),
        (bytes(range(256)) * 4, "not an MCAP"),
        (b"\x89MCAP0\r\n", "cut off before its capture info"),
        (b"\x89MCAP0\r\n" + b"\x01" + (2**40).to_bytes(8, "little") + b"junk", "cut off before"),
    ],
)
def test_unreadable_files_raise_capture_error(tmp_path, content, words):
    p = tmp_path / "bad.mcap"
    p.write_bytes(content)
    with pytest.raises(CaptureError) as e:
        open_mcap(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}: ") and words in msg and "\n" not in msg


def test_missing_file_and_foreign_mcap(tmp_path):
    with pytest.raises(CaptureError, match="No such file"):
        open_mcap(tmp_path / "nope.mcap")
    assert not sniff(tmp_path / "nope.mcap")
    p = tmp_path / "other.mcap"
    with open(p, "wb") as fh:
        w = Writer(fh)
        w.start()
        ch = w.register_channel("/imu", "json", 0)
        w.add_message(ch, 1, b"{}", 1)
        w.finish()
    with pytest.raises(CaptureError, match="no sniffer capture info"):
        open_mcap(p)
    assert read_frames(p) == []


def test_newer_raw_format_is_refused(tmp_path):
    p = tmp_path / "newer.mcap"
    with open(p, "wb") as fh:
        w = Writer(fh)
        w.start()
        w.add_metadata("sniffer.capture", info_to_metadata(INFO))
        ch = w.register_channel("/raw", "json", 0, {"sniffer.format": "3"})
        w.add_message(ch, 1, b'{"kind": "tick", "t_ns": 1}', 1)
        w.finish()
    info, it = open_mcap(p)
    assert info == INFO
    with pytest.raises(CaptureError, match="format '3' is newer"):
        list(it)


def _chunk_offsets(path):
    with open(path, "rb") as fh:
        return [(c.chunk_start_offset, c.chunk_length) for c in make_reader(fh).get_summary().chunk_indexes]


def test_damaged_chunk_is_skipped_announced_and_repair_keeps_the_rest(tmp_path):
    p = tmp_path / "damaged.mcap"
    events = [make_event(i) for i in range(10)]
    write_capture(p, events, flush_interval_s=0, seal_interval_s=0)  # one chunk per event: chunk k+1 holds event k
    start, length = _chunk_offsets(p)[4]
    data = bytearray(p.read_bytes())
    data[start + length - 6] ^= 0xFF
    p.write_bytes(bytes(data))

    src = McapSource(p)
    info = src.open()
    got = list(src.events())
    assert info.baud == INFO.baud and "mcap_unfinished" not in info.extra
    # everything readable, a Gap where event 3 was, from the last good time to the next good byte
    gap = got[3]
    assert got[:3] == events[:3] and got[4:] == events[4:]
    assert isinstance(gap, Gap) and (gap.t_ns, gap.t_end_ns) == (events[2].t_ns, events[4].byte_t_ns[0])
    assert f"at byte {start}" in gap.reason
    assert len(src.damage) == 1 and src.damage[0].startswith(f"{p}: damaged chunk record at byte {start} (")
    assert f"skipped {length} bytes" in src.damage[0]

    out = tmp_path / "fixed.mcap"
    counts = repair(p, out)
    assert counts["messages"] == 1 + 9 and counts["topics"] == {"/capture": 1, "/raw": 9}
    assert counts["skipped"] == [(start, length)] and counts["bytes_dropped"] == length
    assert "chunk record at byte" in counts["problem"] and not counts["was_finished"]
    assert list(open_mcap(out)[1]) == events[:3] + events[4:]
    assert len(messages(out)) == 10


def test_cut_files_read_a_prefix(tmp_path):
    """Cut a finished file around every record boundary and every 7th byte between.

    The reader returns a prefix of what was written, or one clear error.
    """
    p = tmp_path / "full.mcap"
    events = [make_event(i) for i in range(6)]
    frames = real_frames()
    write_capture(p, events, frames, flush_interval_s=0, seal_interval_s=0)
    data = p.read_bytes()
    cuts = set(range(0, len(data), 7))
    pos = 8
    while pos < len(data) - 8:  # walk the records: opcode (1), length (8), body
        cuts |= {pos - 1, pos, pos + 1, pos + 9}
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    cut = tmp_path / "cut.mcap"
    longest = 0
    for n in sorted(cuts):
        cut.write_bytes(data[:n])
        try:
            info, it = open_mcap(cut)
        except CaptureError as e:
            assert "\n" not in str(e)
            continue
        got = list(it)
        assert info.baud == INFO.baud and info.extra["mcap_unfinished"] is True
        assert got == events[: len(got)]
        fr = read_frames(cut)
        assert fr == [frame_record(f, T0) for f in frames[: len(fr)]]
        longest = max(longest, len(got) + len(fr))
    assert longest == len(events) + len(frames)  # a file cut in its summary loses nothing


def test_a_torn_rewrite_of_the_open_chunk_loses_that_chunk_only(tmp_path):
    """A kill inside the one write() that puts the open chunk's new copy over the old leaves the first pages new
    and the rest old: the reader stops at the torn copy, as at any cut, and gives every event of the sealed chunks."""
    p = tmp_path / "live.mcap"
    now = [T0]
    sink = McapSink(p, clock=lambda: now[0], flush_interval_s=1.0, seal_interval_s=10.0)
    sink.start(INFO)
    events = [make_event(i) for i in range(1300)]
    snaps = []
    for k, ev in enumerate(events):
        now[0] = T0 + k * 10_000_000  # 13 s of the sink's clock: one chunk sealed at 10 s, then a copy
        sink.raw(ev)
        if k in (1150, 1299):  # after the copies of 11 s and of 12 s
            snaps.append(p.read_bytes())
    old, new = snaps
    start = len(os.path.commonprefix([old, new]))  # where the copies begin to differ
    assert len(new) > len(old) > start + 1000
    cut = (start + len(old)) // 2
    torn = tmp_path / "torn.mcap"
    torn.write_bytes(new[:cut] + old[cut:])  # the new copy's first bytes, then the old one's
    src = McapSource(torn)
    assert src.open().extra["mcap_unfinished"] is True
    got = list(src.events())
    whole = [e for e in got if not isinstance(e, Gap) or e.reason.startswith("adapter")]
    assert whole == events[: len(whole)] and len(whole) >= 1000  # the sealed chunk's 10 s
    assert len(whole) < 1100  # the copy's events are gone: the one case that loses more than a second
    sink.close()


# -- killed writer -------------------------------------------------------------------------

def test_a_live_files_open_chunk_is_on_disk_every_flush_and_sealed_long(tmp_path):
    """A live capture rewrites its open chunk every flush interval and seals it every seal interval: the
    file as it is on disk at any moment (what a SIGKILL leaves) reads every event older than the flush
    interval, and the finished file holds one chunk per seal interval, not one per flush."""
    p = tmp_path / "live.mcap"
    now = [T0]
    sink = McapSink(p, clock=lambda: now[0], flush_interval_s=1.0, seal_interval_s=10.0)
    sink.start(INFO)
    events = [make_event(i) for i in range(4000)]  # 1 ms apart: 4 s of capture
    for k, ev in enumerate(events):
        now[0] = T0 + k * 10_000_000  # the sink's clock runs ten times the events': 40 s of writing
        sink.raw(ev)
        if k % 97 == 0:  # the file as a SIGKILL would leave it now
            cut = tmp_path / "cut.mcap"
            cut.write_bytes(p.read_bytes())
            got = list(open_mcap(cut)[1]) if k else []
            assert got == events[: len(got)]
            assert len(got) >= k - 100  # all but the last second of the sink's clock (100 events)
    size = sink.size  # what size rotation reads: the copy on disk and the open chunk are not counted twice
    sink.close()
    assert abs(p.stat().st_size - size) < 0.05 * size
    chunks = _chunk_offsets(p)
    assert 4 <= len(chunks) <= 6  # 40 s sealed every 10 s (and the /capture chunk), not 40 chunks
    with open(p, "rb") as fh:
        msgs = [m for _s, c, m in make_reader(fh).iter_messages() if c.topic == "/raw"]
    assert len(msgs) == len(events)
    assert list(open_mcap(p)[1]) == events



KILL_CHILD = r"""
import sys, time
sys.path.insert(0, sys.argv[2])
from test_mcap import INFO, make_event
from sniffer.formats.mcap.sink import McapSink
sink = McapSink(sys.argv[1], flush_interval_s=0.2)
sink.start(INFO)
i = 0
while True:
    sink.raw(make_event(i))
    i += 1
    if i == 100:
        sink.flush()
        print("flushed", flush=True)
    time.sleep(0.002)
"""


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
def test_sigkilled_writer_is_readable_and_repairable(tmp_path):
    p = tmp_path / "killed.mcap"
    began = time.monotonic()
    child = subprocess.Popen([sys.executable, "-c", KILL_CHILD, str(p), TESTS], stdout=subprocess.PIPE)
    try:
        assert child.stdout.readline() == b"flushed\n"
        time.sleep(max(0.0, 2.5 - (time.monotonic() - began)))  # let several timed flushes happen
    finally:
        os.kill(child.pid, signal.SIGKILL)
        child.wait()
        child.stdout.close()
    assert child.returncode == -signal.SIGKILL

    info, it = open_mcap(p)
    got = list(it)
    assert (info.baud, info.parity, info.t0_ns, info.devices) == (19200, "E", T0, INFO.devices)
    assert info.extra["mcap_unfinished"] is True
    assert len(got) >= 100
    assert got == [make_event(i) for i in range(len(got))]

    # mcap's default reader needs the footer the killed writer never wrote
    # (it reads the tail as a footer: which error depends on the bytes found there)
    with open(p, "rb") as fh, pytest.raises((McapError, ValueError, struct.error)):
        list(make_reader(fh).iter_messages())

    out = tmp_path / default_output("killed.mcap")
    counts = repair(p, out)
    assert counts["topics"] == {"/capture": 1, "/raw": len(got)} and not counts["was_finished"]
    assert counts["bytes_kept"] + counts["bytes_dropped"] == counts["bytes_in"] == p.stat().st_size
    with open(out, "rb") as fh:
        reader = make_reader(fh)
        assert reader.get_summary().statistics.message_count == len(got) + 1
        assert [m.name for m in reader.iter_metadata()] == ["sniffer.capture", "foxglove"]
    info2, it2 = open_mcap(out)
    assert "mcap_unfinished" not in info2.extra and list(it2) == got
    with pytest.raises(CaptureError, match="different output"):
        repair(out, out)


# -- full disk -----------------------------------------------------------------------------------

FULL_CHILD = r"""
import json, resource, sys
sys.path.insert(0, sys.argv[2])
from test_mcap import INFO, make_event, real_frames
from sniffer.formats.mcap.sink import CaptureStorageError, McapSink
limit = int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))  # writes past it fail with EFBIG
sink = McapSink(sys.argv[1], flush_interval_s=0, seal_interval_s=0)
sink.start(INFO)
accepted = 0
try:
    for i in range(100_000):
        sink.raw(make_event(i))
        accepted += 1
    raise SystemExit("the file size limit was never reached")
except CaptureStorageError as e:
    error = str(e)
on_disk = sink.bytes_written
for f in real_frames():  # after the one error: quietly dropped
    sink.frame(f)
sink.raw(make_event(0))
sink.flush()
sink.maybe_flush()
sink.close()
sink.close()
print(json.dumps({"accepted": accepted, "error": error, "on_disk": on_disk}))
"""


@pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin", reason="needs RLIMIT_FSIZE semantics of Linux")
def test_full_disk_stops_cleanly_and_keeps_a_readable_file(tmp_path):
    pytest.importorskip("resource")
    p = tmp_path / "full.mcap"
    limit = 20_000
    run = subprocess.run(
        [sys.executable, "-c", FULL_CHILD, str(p), TESTS, str(limit)], capture_output=True, timeout=60
    )
    assert run.returncode == 0, run.stderr.decode()
    res = json.loads(run.stdout)
    assert res["error"].startswith(f"{p}: cannot write capture (") and "\n" not in res["error"]
    assert 0 < res["accepted"] < 1000
    assert p.stat().st_size == res["on_disk"] <= limit  # cut back to whole records, nothing after

    info, it = open_mcap(p)
    assert info == CaptureInfo.from_dict({**INFO.to_dict(), "extra": {"mcap_unfinished": True}})
    assert list(it) == [make_event(i) for i in range(res["accepted"])]  # every accepted event flushed

    counts = repair(p, tmp_path / "full.fixed.mcap")
    assert counts["bytes_dropped"] == 0 and counts["topics"]["/raw"] == res["accepted"]
    assert len(messages(tmp_path / "full.fixed.mcap")) == res["accepted"] + 1


def test_unwritable_path_is_a_storage_error(tmp_path):
    with pytest.raises(CaptureStorageError, match="cannot create capture file"):
        McapSink(tmp_path / "no" / "such" / "dir.mcap")


def test_scan_skipping_a_topic_yields_the_same_other_messages():
    """A replay reads /raw only: the scan does not build the /frames messages, and loses nothing else."""
    from mcap.records import Message

    from sniffer.formats.mcap.scan import Scan, open_file

    from pathlib import Path

    path = Path(__file__).resolve().parent.parent / "captures" / "sim" / "errors.mcap"

    def messages(skip):
        fh, size, tail_ok = open_file(path)
        with fh:
            scan = Scan(fh, size, tail_ok=tail_ok, skip_topics=skip)
            return [(scan.topic(m), m.sequence, m.log_time, m.data) for m in scan.records() if isinstance(m, Message)]

    every = messages(frozenset())
    raw_only = messages(frozenset({"/frames"}))
    assert {t for t, *_ in every} == {"/capture", "/raw", "/frames"}
    assert raw_only == [m for m in every if m[0] != "/frames"] and len(raw_only) > 100


def test_the_open_chunk_is_estimated_at_the_compression_so_far(tmp_path):
    """What a size rotation counts (McapSink.size): the open chunk, estimated at the compression of the chunks
    before it, comes within a tenth of what writing it adds, its summary entry included; nothing is guessed
    before a chunk was written, and a segment's writer starts from the compression of the one before."""
    import io
    import random

    from sniffer.formats.mcap.writer import McapWriter

    rng = random.Random(3)

    def message(i):
        return json.dumps({"t": i, "raw": bytes(rng.randrange(4) for _ in range(12)).hex(), "unit": 1 + i % 3,
                           "points": [{"name": "Output frequency", "value": rng.randrange(6000) / 100}]}).encode()

    w = McapWriter(io.BytesIO(), chunk_size=1 << 30)
    w.start()
    chs = [w.register_channel(f"/c{k}", "json", w.register_schema("s", "jsonschema", b"{}")) for k in range(5)]
    for i in range(2000):
        w.add_message(chs[i % 5], i, message(i), i)
    assert w.open_chunk_bytes() == 0  # no compression known yet
    w.flush()
    raw, packed = w.packing
    assert 0 < packed < raw / 3
    for i in range(2000, 5000):
        w.add_message(chs[i % 5], i, message(i), i)
    guess = w.open_chunk_bytes()
    before = w._out.tell() + w.summary_bytes
    w.flush()
    grew = w._out.tell() + w.summary_bytes - before
    assert abs(guess - grew) < grew / 10, (guess, grew)
    nxt = McapWriter(io.BytesIO(), packing=w.packing)
    nxt.start()
    nxt.add_message(nxt.register_channel("/c", "json", nxt.register_schema("s", "jsonschema", b"{}")), 1, message(1), 1)
    assert 0 < nxt.open_chunk_bytes() < len(message(1)) + 200


def test_our_mcap_writer_reads_back_through_the_mcap_library_index_and_all(tmp_path):
    """sniffer.formats.mcap.writer is checked by the reference reader: summary, chunk indexes, message indexes, CRCs."""
    from mcap.reader import SeekingReader, StreamReader

    from sniffer.formats.mcap.writer import McapWriter

    path = tmp_path / "w.mcap"
    with open(path, "wb") as fh:
        w = McapWriter(fh, chunk_size=300)  # many chunks
        w.start(profile="p", library="lib")
        w.add_metadata("m", {"a": "1"})
        sid = w.register_schema("s", "jsonschema", b"{}")
        a, b = w.register_channel("/a", "json", sid, {"k": "v"}), w.register_channel("/b", "json", sid)
        sent = []
        for i in range(200):
            ch = a if i % 3 else b
            t = 1_000 + 10 * i - (5 if i % 7 == 0 else 0)  # not quite in order, as on a bus
            data = f'{{"i": {i}}}'.encode()
            w.add_message(ch, t, data, t, i)
            sent.append((ch, t, data, i))
        w.finish()
    with open(path, "rb") as fh:
        reader = SeekingReader(fh, validate_crcs=True)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 200 and len(summary.chunk_indexes) > 5
        assert summary.statistics.channel_message_counts == {a: 133, b: 67}
        assert {c.topic for c in summary.channels.values()} == {"/a", "/b"}
        assert summary.channels[a].metadata == {"k": "v"}
        got = [(m.channel_id, m.log_time, m.data, m.sequence)
               for _s, _c, m in reader.iter_messages(log_time_order=False)]
        assert got == sent
        in_order = [m.log_time for _s, _c, m in reader.iter_messages(topics=["/a"])]
        assert in_order == sorted(t for ch, t, _d, _i in sent if ch == a)
        assert [(m.name, m.metadata) for m in reader.iter_metadata()] == [("m", {"a": "1"})]
        fh.seek(0)
        records = list(StreamReader(fh, validate_crcs=True).records)
        assert sum(type(r).__name__ == "MessageIndex" for r in records) > 5
