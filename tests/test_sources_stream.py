"""FileSource: one streaming interface for every capture file format.

Streams: the events equal what the old read-everything-then-sort readers
gave; memory does not grow with the file; stop() and close() end a replay;
a FIFO is refused without blocking.  Damage: each reader skips what it
cannot read, yields a Gap there and reports it in `damage`, and everything
readable still comes through.
"""

from __future__ import annotations

import csv
import os
import random
import struct
import threading
import tracemalloc
from pathlib import Path

import pytest
from helpers import export, run_events
from refdata import SIGROK, SIGROK_NAMES

from sniffer.events import Chunk, Gap
from sniffer.line import LineSettings
from sniffer.formats.pcap.format import global_header, packet, pcapng_header, pcapng_packet
from sniffer.events import CaptureError
from sniffer.formats.bytecsv.reader import write_byte_csv
from sniffer.formats.csvstream import PER_BYTE_CHUNK, REORDER_WINDOW
from sniffer.sources.files import FORMATS, FileSource, open_replay
from sniffer.formats.timeparse import seconds_to_ns

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
WIZ = SIGROK / "wizmodbus.bytes.csv"
L96 = LineSettings(9600)


def replay(path, fmt="auto"):
    src = FileSource(path, fmt)
    info = src.open()
    return src, info, list(src.events())


def chunks_of(events):
    return [e for e in events if type(e) is Chunk]


def gaps_of(events):
    return [e for e in events if type(e) is Gap]


def data_of(events) -> bytes:
    return b"".join(e.data for e in chunks_of(events))


# -- the reference: what the byte CSV reader did before it streamed ---------------------------
def sorted_reference(rows):
    """Today's chunks_from_rows on today's read_rows: the whole file, stably sorted by time."""
    rows = sorted(rows, key=lambda r: r[0])
    per_read = any(rows[i][0] == rows[i - 1][0] and rows[i][1] == rows[i - 1][1] for i in range(1, len(rows)))
    out, i, n = [], 0, len(rows)
    while i < n:
        j = i + 1
        if per_read:
            while j < n and rows[j][0] == rows[i][0] and rows[j][1] == rows[i][1]:
                j += 1
        else:
            while j < n and j - i < PER_BYTE_CHUNK and rows[j][1] == rows[i][1]:
                j += 1
        part = rows[i:j]
        flags = tuple((k, r[3]) for k, r in enumerate(part) if r[3])
        times = None if per_read else tuple(r[0] for r in part)
        out.append(Chunk(part[0][0], bytes(r[2] for r in part), times, flags, part[0][1]))
        i = j
    return out


def rows_of(path):
    with open(path, newline="") as fh:
        return [(seconds_to_ns(r["t_s"]), r["channel"].strip(), int(r["byte_hex"], 16), r["flags"] or None)
                for r in csv.DictReader(fh)]


def write_rows(path, rows):
    with open(path, "w", newline="") as fh:
        fh.write("t_s,channel,byte_hex,flags\n")
        for t, ch, b, flag in rows:
            fh.write(f"{t // 10**9}.{t % 10**9:09d},{ch},{b:02x},{flag or ''}\n")
    return path


@pytest.mark.parametrize("name", SIGROK_NAMES)
def test_streamed_byte_csv_equals_the_sorted_reader(name):
    path = SIGROK / f"{name}.bytes.csv"
    src, info, events = replay(path)
    assert src.format == "csv" and src.damage == []
    assert events == sorted_reference(rows_of(path))
    assert info.time_source == ("read" if events[0].byte_t_ns is None else "byte")


def test_per_read_csv_from_a_usb_adapter_equals_the_sorted_reader(tmp_path):
    from sniffer.simulator import get_scenario, simulate, usb_chunks

    sc = get_scenario("default")
    chunks = list(usb_chunks(list(simulate(sc, sc.line, 3.0, 1)), seed=1))
    p = tmp_path / "usb.csv"
    write_byte_csv(str(p), chunks)
    src, info, events = replay(p)
    assert info.time_source == "read" and events == sorted_reference(rows_of(p))
    assert data_of(events) == b"".join(c.data for c in chunks)


def test_two_channels_written_apart_are_merged_by_time(tmp_path):
    """TX and RX probed separately: each channel's rows in blocks, up to a window apart in the file."""
    rng = random.Random(7)
    rows = []
    t = 0
    for _ in range(30_000):
        t += rng.randint(1, 3) * 1_000_000
        rows.append((t, rng.choice("AB"), rng.randrange(256), rng.choice([None] * 20 + ["parity", "framing"])))
    in_file = []
    block = {"A": [], "B": []}
    for r in rows:  # hold each channel back for up to 1000 rows
        block[r[1]].append(r)
        if len(block[r[1]]) >= rng.randint(1, 1000):
            in_file += block[r[1]]
            block[r[1]] = []
    in_file += block["A"] + block["B"]
    assert in_file != rows
    p = write_rows(tmp_path / "two.csv", in_file)
    src, info, events = replay(p)
    assert src.damage == [] and info.time_source == "byte"
    assert events == sorted_reference(in_file)
    assert max(len(c.data) for c in events) <= PER_BYTE_CHUNK
    assert info.extra["channels"] == ["A", "B"]


def test_long_single_channel_run_is_cut_at_4096_bytes(tmp_path):
    rows = [(i * 1000, "RX", i & 0xFF, None) for i in range(10_000)]
    src, _info, events = replay(write_rows(tmp_path / "long.csv", rows))
    assert [len(c.data) for c in events] == [4096, 4096, 1808]
    assert events == sorted_reference(rows)


def test_row_out_of_order_beyond_the_window_is_kept_late_and_reported(tmp_path):
    rows = [(10**6 + i * 1000, "RX", i & 0xFF, None) for i in range(REORDER_WINDOW + 500)]
    late = (5, "RX", 0xAB, None)  # belongs at the start, arrives after the window has moved on
    p = write_rows(tmp_path / "late.csv", rows[:REORDER_WINDOW + 200] + [late] + rows[REORDER_WINDOW + 200:])
    src, _info, events = replay(p)
    assert len(data_of(events)) == len(rows) + 1  # no byte lost
    times = [t for c in chunks_of(events) for t in c.byte_t_ns]
    assert times == sorted(times)  # replayed in time order: the late byte at the time it came
    assert len(src.damage) == 1 and f"late.csv:{REORDER_WINDOW + 202}: row at 0.000000005 s" in src.damage[0]
    assert "reorder window" in src.damage[0]


# -- memory ------------------------------------------------------------------------------------
def _peak(path, fmt="auto") -> int:
    src = FileSource(path, fmt)
    src.open()
    tracemalloc.start()
    try:
        n = sum(1 for _ in src.events())
        return n, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_file(tmp_path, monkeypatch):
    """Five to ten times the rows or packets, about the same peak: every reader streams.

    The CSV reorder window is made small so that a short file is long next to it; the smaller CSV
    is still long enough to fill the reader's fixed buffers (64 KB blocks of lines, 512-row lists,
    4,096-byte chunks), so that the two peaks compare steady states."""
    from sniffer.formats import csvstream

    monkeypatch.setattr(csvstream, "REORDER_WINDOW", 64)

    def csv_file(n, name):
        return write_rows(tmp_path / name, [(i * 573_000, "RX", i & 0xFF, None) for i in range(n)])

    def pcap_file(n, name):
        p = tmp_path / name
        with open(p, "wb") as fh:
            fh.write(global_header())
            for i in range(n):
                fh.write(packet(10**18 + i * 10**7, bytes([1, 3, i & 0xFF, 0, 0, 2, 0x44, 0x0B])))
        return p

    for make, small, big in ((csv_file, 30_000, 200_000), (pcap_file, 2_000, 20_000)):
        n1, peak1 = _peak(make(small, f"s{small}"))
        n2, peak2 = _peak(make(big, f"b{big}"))
        assert n2 > 5 * n1
        assert peak2 < 1.5 * peak1 + 200_000, (make.__name__, peak1, peak2)


# -- the FileSource interface ----------------------------------------------------------------
def test_open_is_idempotent_events_once_close_twice(tmp_path):
    src = FileSource(WIZ)
    assert src.position() is None and src.format == "auto"
    info = src.open()
    assert src.open() is info and src.format == "csv" and src.path == str(WIZ)
    it = src.events()
    with pytest.raises(RuntimeError):
        src.events()
    first = next(it)
    assert type(first) is Chunk
    pos = src.position()
    assert pos is not None and 0 < pos[0] <= pos[1] == WIZ.stat().st_size
    rest = list(it)
    assert len(rest) > 10
    src.close()
    src.close()
    info2, events = open_replay(str(WIZ))
    assert [first, *rest] == list(events) and info2.time_source == info.time_source


@pytest.mark.parametrize("fmt", ["csv", "mcap", "pcap"])
def test_stop_from_another_thread_ends_events(tmp_path, fmt):
    path = {"csv": WIZ, "mcap": CAPTURES / "sim" / "fast.mcap", "pcap": tmp_path / "w.pcap"}[fmt]
    if fmt == "pcap":
        export(WIZ, "pcap", path, "--baud", "9600")
    src = FileSource(path)
    src.open()
    got = []
    seen_one = threading.Event()
    go_on = threading.Event()

    def consume():
        for ev in src.events():
            got.append(ev)
            seen_one.set()
            go_on.wait(5)

    t = threading.Thread(target=consume)
    t.start()
    assert seen_one.wait(5)
    src.stop()
    go_on.set()
    t.join(5)
    assert not t.is_alive() and len(got) == 1


def test_close_under_a_running_replay_ends_it(tmp_path):
    src = FileSource(CAPTURES / "sim" / "fast.mcap")
    src.open()
    it = src.events()
    next(it)
    src.close()
    assert list(it) == []


def test_a_fifo_is_refused_at_once(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    result = []

    def try_open(fmt):
        try:
            FileSource(fifo, fmt).open()
        except CaptureError as e:
            result.append(str(e))

    for fmt in FORMATS:  # auto-detection must not read it either
        t = threading.Thread(target=try_open, args=(fmt,), daemon=True)
        t.start()
        t.join(10)
        assert not t.is_alive(), f"opening a FIFO as {fmt} blocked"
    assert len(result) == len(FORMATS)
    assert all(r == f"{fifo}: not a regular file (a FIFO): reading it would block forever or never end"
               for r in result)


@pytest.mark.parametrize("case, words", [
    ("missing", "no such file"), ("dir", "is a directory"), ("empty", "empty file"),
    ("garbage", "unknown capture format"), ("fmt", "unknown input format 'xml'"),
    ("csv-header", "not a byte CSV"), ("pcap-header", "truncated pcap header"),
])
def test_what_cannot_be_replayed_is_one_line(tmp_path, case, words):
    p = tmp_path / "x"
    fmt = "auto"
    if case == "dir":
        p.mkdir()
    elif case == "empty":
        p.write_bytes(b"")
    elif case == "garbage":
        p.write_bytes(bytes(range(256)) * 10)
    elif case == "fmt":
        p.write_text("t_s,channel,byte_hex,flags\n0.1,A,01,\n")
        fmt = "xml"
    elif case == "csv-header":
        p.write_text("time," + "x" * 100_000 + "\n0.1,A,01,\n")
        fmt = "csv"
    elif case == "pcap-header":
        p.write_bytes(global_header()[:20])
    with pytest.raises(CaptureError) as e:
        FileSource(p, fmt).open()
    msg = str(e.value)
    assert words in msg and "\n" not in msg and len(msg) < 400, msg


# -- damage: skipped, announced, a Gap, the rest still read ------------------------------------
def _wiz_pcap(tmp_path, ext="pcap") -> tuple[Path, list[int]]:
    p = tmp_path / f"wiz.{ext}"
    export(WIZ, "pcap", p, "--baud", "9600")
    data = p.read_bytes()
    offsets = []
    if ext == "pcap":
        pos = 24
        while pos < len(data):
            offsets.append(pos)
            pos += 16 + struct.unpack_from("<I", data, pos + 8)[0]
    else:
        pos = 0
        while pos < len(data):
            offsets.append(pos)
            pos += struct.unpack_from("<I", data, pos + 4)[0]
    return p, offsets


def test_pcap_record_length_flipped_is_skipped_and_announced(tmp_path):
    p, offsets = _wiz_pcap(tmp_path)
    _src, _info, clean = replay(p)
    data = bytearray(p.read_bytes())
    at = offsets[40]
    data[at + 10] ^= 0x3D  # incl_len of record 40 becomes ~4 million
    p.write_bytes(bytes(data))
    src, _info, events = replay(p)
    chunks = chunks_of(events)
    assert len(chunks) == len(chunks_of(clean)) - 1  # only the damaged record is lost
    assert [c.data for c in chunks] == [c.data for c in chunks_of(clean) if c is not chunks_of(clean)[40]]
    (gap,) = gaps_of(events)
    assert events[events.index(gap) + 1:] == clean[clean.index(chunks_of(clean)[41]) - 1:]  # its Tick, then on
    assert len(src.damage) == 1
    line = src.damage[0]
    assert line.startswith(f"{p}: pcap record at byte {at} claims ") and "(snaplen 65535)" in line
    assert f"skipped {offsets[41] - at} bytes to the next plausible record" in line
    frames = run_events(events, L96)
    marked = [f for f in frames if "source.gap" in [a.code for a in f.annotations]]
    assert len(marked) == 1 and marked[0].raw == chunks_of(clean)[41].data


def test_pcap_cut_in_its_last_record_is_announced(tmp_path):
    p, _offsets = _wiz_pcap(tmp_path)
    _src, _info, clean = replay(p)
    p.write_bytes(p.read_bytes()[:-3])
    src, _info, events = replay(p)
    assert chunks_of(events) == chunks_of(clean)[:-1] and not gaps_of(events)
    assert len(src.damage) == 1 and "the last record (at byte" in src.damage[0] and "is cut off" in src.damage[0]


def test_pcapng_block_length_flipped_resyncs_on_the_trailing_length(tmp_path):
    p, offsets = _wiz_pcap(tmp_path, "pcapng")
    _src, _info, clean = replay(p)
    data = bytearray(p.read_bytes())
    at = offsets[30]  # SHB, IDB, then packets: block 30 holds packet 28
    data[at + 6] ^= 0x01  # its length now runs past the end of the file
    p.write_bytes(bytes(data))
    src, _info, events = replay(p)
    assert [c.data for c in chunks_of(events)] == [c.data for i, c in enumerate(chunks_of(clean)) if i != 28]
    assert len(gaps_of(events)) == 1 and len(src.damage) == 1
    assert src.damage[0].startswith(f"{p}: pcapng block at byte {at} claims ")
    assert f"skipped {offsets[31] - at} bytes" in src.damage[0]


def test_pcapng_unknown_block_type_is_reported(tmp_path):
    from sniffer.events import CaptureInfo

    p = tmp_path / "x.pcapng"
    frame = bytes.fromhex("010300000002c40b")
    strange = pcapng_packet(2 * 10**9, frame)
    strange = struct.pack("<I", 0x77) + strange[4:]
    head = pcapng_header(CaptureInfo())
    p.write_bytes(head + pcapng_packet(10**9, frame) + strange + pcapng_packet(3 * 10**9, frame))
    src, _info, events = replay(p)
    assert len(chunks_of(events)) == 2 and len(gaps_of(events)) == 1
    assert src.damage == [f"{p}: block of unknown type 0x00000077 at byte {len(head) + 40} skipped (40 bytes)"]


def test_mcap_damaged_length_in_the_middle_keeps_the_rest(tmp_path):
    from test_mcap import INFO, _chunk_offsets, make_event, write_capture

    p = tmp_path / "len.mcap"
    events = [make_event(i) for i in range(12)]
    write_capture(p, events, flush_interval_s=0, seal_interval_s=0)
    start, _length = _chunk_offsets(p)[6]
    data = bytearray(p.read_bytes())
    data[start + 4] ^= 0x20  # the chunk's record length: now far past the end of the file
    p.write_bytes(bytes(data))
    src, info, got = replay(p)
    assert info.baud == INFO.baud
    assert [e for e in got if type(e) is not Gap or "damaged" not in e.reason] == events[:5] + events[6:]
    assert len(src.damage) == 1 and f"damaged chunk record at byte {start} (it runs past the end" in src.damage[0]


def test_mcap_cut_short_is_not_damage(tmp_path):
    from test_mcap import make_event, write_capture

    p = tmp_path / "cut.mcap"
    events = [make_event(i) for i in range(12)]
    write_capture(p, events, flush_interval_s=0, seal_interval_s=0)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) * 2 // 3])
    src, info, got = replay(p)
    assert info.extra["mcap_unfinished"] is True and src.damage == []
    assert got == events[: len(got)] and len(got) > 3


@pytest.mark.parametrize("fmt", ["csv", "saleae"])
def test_one_bad_row_is_skipped_and_announced(tmp_path, fmt):
    rows = rows_of(WIZ)
    p = tmp_path / f"bad.{fmt}"
    lines = []
    for t, ch, b, _flag in rows:
        ts = f"{t // 10**9}.{t % 10**9:09d}"
        lines.append(f"{ts},{ch},{b:02x},\n" if fmt == "csv" else f'"{ch}","data",{ts},0.000937,0x{b:02X}\n')
    header = "t_s,channel,byte_hex,flags\n" if fmt == "csv" else "name,type,start_time,duration,data\n"
    bad_text = "1e999999" + "7" * 100_000
    bad = lines[100].replace(lines[100].split(",")[0 if fmt == "csv" else 2], bad_text, 1)
    p.write_text(header + "".join(lines[:100]) + bad + "".join(lines[101:]))
    src, _info, events = replay(p)
    assert data_of(events) == bytes(b for _t, _c, b, _f in rows[:100] + rows[101:])
    (gap,) = gaps_of(events)
    assert (gap.t_ns, gap.t_end_ns) == (rows[99][0], rows[101][0])
    assert len(src.damage) == 1 and src.damage[0].startswith(f"{p}:102: bad row ")
    assert len(src.damage[0]) < 400 and " characters)" in src.damage[0]  # the row is shortened, its length said


def test_csv_cut_mid_row_at_the_end_is_announced(tmp_path):
    text = WIZ.read_text()
    p = tmp_path / "cut.csv"
    p.write_text(text[: text.rindex("\n") + 1] + "5.99,RX,0")
    src, _info, events = replay(p)
    assert len(data_of(events)) == len(rows_of(WIZ))
    assert len(src.damage) == 1 and "the file ends mid-row" in src.damage[0]


def test_garbage_csv_is_fatal_with_its_first_bad_row(tmp_path):
    p = tmp_path / "junk.csv"
    p.write_text("t_s,channel,byte_hex,flags\n" + "x,y,z,\n" * 1000)
    with pytest.raises(CaptureError) as e:
        FileSource(p).open()
    assert str(e.value) == (f"{p}:2: bad row 'x,y,z,' (not a number of seconds: 'x'); "
                            "no row of this byte CSV is readable")


def test_triggered_saleae_export_is_shifted_to_start_at_zero(tmp_path):
    p = tmp_path / "trig.csv"
    p.write_text("name,type,start_time,duration,data\n"
                 '"s","data",-0.5,0.001,0x01\n"s","data",-0.499,0.001,0x03\n"s","data",0.25,0.001,0x05\n')
    src, info, events = replay(p)
    assert src.format == "saleae" and src.damage == []
    assert events == [Chunk(0, b"\x01\x03\x05", (0, 1_000_000, 750_000_000), (), "s")]
    assert info.extra["saleae_time_offset_ns"] == 500_000_000


def test_mcap_channels_lost_with_the_first_chunk_come_from_the_summary(tmp_path):
    from sniffer.formats.mcap.repair import repair
    from test_mcap import _chunk_offsets, make_event, write_capture

    p = tmp_path / "first.mcap"
    events = [make_event(i) for i in range(8)]
    write_capture(p, events, flush_interval_s=0, seal_interval_s=0)  # chunk 0: schemas, channels and /capture
    start, length = _chunk_offsets(p)[0]
    data = bytearray(p.read_bytes())
    data[start + length - 6] ^= 0xFF
    p.write_bytes(bytes(data))
    src, _info, got = replay(p)
    assert [e for e in got if type(e) is not Gap or "damaged" not in e.reason] == events
    assert len(src.damage) == 1 and "damaged chunk record at byte" in src.damage[0]
    counts = repair(p, tmp_path / "fixed.mcap")
    assert counts["topics"] == {"/raw": 8} and counts["orphans"] == 0
    assert replay(tmp_path / "fixed.mcap")[2] == events


def _library_capture(path, events) -> None:
    """A capture as the mcap library's Writer lays it out: channel records inside the first chunk
    (sniffer's own writer puts them before any chunk, where damage to a chunk cannot take them)."""
    import orjson
    from mcap.writer import Writer
    from test_mcap import INFO

    from sniffer.formats.mcap.format import CHANNELS, METADATA_NAME, RAW_FORMAT, encode_event, info_to_metadata

    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="mcap library")
        w.add_metadata(METADATA_NAME, info_to_metadata(INFO))
        ids = {topic: w.register_channel(topic, "json", w.register_schema(name, "jsonschema", orjson.dumps(schema)),
                                         {"sniffer.format": RAW_FORMAT})
               for topic, name, schema in CHANNELS}
        w.add_message(ids["/capture"], 0, orjson.dumps(INFO.to_dict()), 0, 0)
        for i, ev in enumerate(events):
            w.flush()  # one chunk per event
            w.add_message(ids["/raw"], ev.t_ns, encode_event(ev), ev.t_ns, i)
        w.finish()


def test_mcap_channels_lost_in_an_unfinished_file_are_reported(tmp_path):
    from test_mcap import _chunk_offsets, make_event

    p = tmp_path / "first.mcap"
    events = [make_event(i) for i in range(8)]
    _library_capture(p, events)
    start, length = _chunk_offsets(p)[0]
    (last_start, _len) = _chunk_offsets(p)[-1]
    data = bytearray(p.read_bytes()[:last_start + 20])  # killed: no summary
    data[start + length - 6] ^= 0xFF
    p.write_bytes(bytes(data))
    src, _info, got = replay(p)
    assert got == []
    assert len(src.damage) == 2
    assert src.damage[1] == f"{p}: 7 messages skipped: the definition of their channel (2) was lost"
