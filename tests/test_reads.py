"""Reads marked with their frames (analysis/reads.py), their line on the viewers' stream, and the TUI's ring of them."""

import random

import pytest
from tui_helpers import SIM, SIM_CAPTURES, frames_from_reads, replay_frames, replay_reads

from sniffer.events import Chunk
from sniffer.analysis.reads import Read, ReadMarker
from sniffer.formats.records import loads
from sniffer.sources.files import open_replay
from sniffer.processes.stream import CONTROL_PREFIX, parse_reads, read_item, reads_line
from sniffer.tui.readring import ReadRing


def chunks_of(name: str) -> list[Chunk]:
    _, events = open_replay(str(SIM / name))
    return [ev for ev in events if type(ev) is Chunk]


@pytest.mark.parametrize("name", SIM_CAPTURES)
def test_every_byte_of_every_read_is_marked_with_its_frame(name):
    """As the TUI's sink marks them on a replay: one Read per Chunk, and the frames rebuilt from the reads'
    bytes are the frames (a frame split across reads, several glued into one)."""
    reads = replay_reads(name)
    chunks = chunks_of(name)
    _, frames, _ = replay_frames(name)
    assert [(r.t_ns, r.data) for r in reads] == [(c.t_ns, c.data) for c in chunks]
    assert [r.offset for r in reads] == [sum(len(c.data) for c in chunks[:i]) for i in range(len(chunks))]
    assert frames_from_reads(reads) == {f.index: f.raw for f in frames}
    assert sum(len(r.starts()) for r in reads) == len(frames)  # each frame begins once
    if name in ("errors.mcap", "fast.mcap"):  # USB reads that split frames and glue several into one
        assert any(r.cont for r in reads) and any(len(r.marks) > 2 for r in reads)


@pytest.mark.parametrize("seed", range(5))
def test_marks_do_not_depend_on_how_chunks_and_frames_interleave(seed):
    """The publisher takes chunks and frames in batches; the sink gets each chunk before its frames."""
    chunks = chunks_of("fast.mcap")
    _, frames, _ = replay_frames("fast.mcap")
    order = ["chunk"] * len(chunks) + ["frame"] * len(frames)  # each in its order, merged at random
    random.Random(seed).shuffle(order)
    cs, fs = iter(chunks), iter(frames)
    m = ReadMarker()
    out = []
    for kind in order:
        if kind == "chunk":
            out += m.chunk(next(cs))
        else:
            f = next(fs)
            out += m.frame(f.index, len(f.raw))
    out += m.flush()
    assert out == replay_reads("fast.mcap")


def test_a_read_waits_until_its_bytes_are_framed():
    m = ReadMarker()
    assert m.chunk(Chunk(10, b"\x01\x03\x00\x00")) == []
    assert m.chunk(Chunk(20, b"\x00\x02\xc4\x0b\x01")) == []
    first = m.frame(0, 8)  # the first read is whole; the second's last byte is not framed yet
    assert first == [Read(10, 0, b"\x01\x03\x00\x00", ((0, 0),))]
    assert m.frame(1, 3) == [Read(20, 4, b"\x00\x02\xc4\x0b\x01", ((0, 0), (4, 1)), cont=True)]
    assert m.chunk(Chunk(30, b"\xff\xff", (28, 29))) == [Read(30, 9, b"\xff\xff", ((0, 1),), True, 29)]
    r = Read(20, 4, b"\x00\x02\xc4\x0b\x01", ((0, 0), (4, 1)), cont=True)
    assert r.starts() == {4} and r.frames == (0, 1) and r.span_of(0) == (0, 4) and r.span_of(1) == (4, 5)
    assert [r.frame_at(k) for k in range(5)] == [0, 0, 0, 0, 1]


def test_reads_travel_on_the_stream_as_they_are():
    reads = replay_reads("errors.mcap") + [Read(5_000, 7, b"\x01\x02", ((0, 3),), True, 6_000, "rx")]
    t0 = 123_456_789
    shifted = [Read(r.t_ns + t0, r.offset, r.data, r.marks, r.cont,
                    None if r.last_ns is None else r.last_ns + t0, r.channel) for r in reads]
    line = reads_line([read_item(r, t0) for r in shifted])
    assert line.startswith(CONTROL_PREFIX) and line.endswith(b"\n") and line.count(b"\n") == 1
    assert parse_reads(loads(line), t0) == shifted
    assert len(line) < 2.5 * sum(len(r.data) for r in reads) + 40 * len(reads)  # compact: hex plus a little


def test_the_ring_keeps_the_last_reads_and_finds_a_frames_first_byte():
    reads = replay_reads("errors.mcap")
    ring = ReadRing(limit=100)
    for k in range(0, len(reads), 7):
        ring.add(reads[k:k + 7])
    assert 75 <= len(ring) <= 100 and ring.end_seq == len(reads)
    assert ring.reads == reads[ring.first_seq:]
    for seq in range(ring.first_seq + 1, ring.end_seq):
        r = ring.get(seq)
        for p, index in r.marks:
            if p or not r.cont:  # the frame begins in this read: found here
                assert ring.find(index) == seq
            else:  # it began earlier
                assert ring.find(index) < seq
    assert ring.find(reads[0].marks[0][1]) is None  # older than the ring
    byte_capped = ReadRing(limit=10_000, max_bytes=1000)
    byte_capped.add(reads)
    assert byte_capped.size <= 1000 and byte_capped.reads == reads[byte_capped.first_seq:]
    assert byte_capped.size == sum(len(r.data) for r in byte_capped.reads)
    # stepping through frames from read to read
    seq = ring.first_seq + 10
    index = ring.get(seq).marks[-1][1]
    nxt = ring.frames_between(seq, index, True)
    assert nxt == index + 1 and ring.frames_between(seq, nxt, False) == index


def test_a_read_after_a_stall_says_so_on_its_way_to_every_viewer():
    """A live reader that stalled (Chunk.unseen_ns) marks its read: through the marker, and through the
    viewers' stream whatever else the read carries (per read or per byte, one link or several)."""
    marker = ReadMarker()
    reads = marker.chunk(Chunk(10_000, b"\x01\x03", unseen_ns=None))
    reads += marker.chunk(Chunk(95_000_000, b"\x00\x00", unseen_ns=84_000_000))
    reads += marker.frame(0, 4)
    assert [r.unseen_ns for r in reads] == [None, 84_000_000]
    t0 = 5_000
    variants = [reads[1], Read(90_000_000, 4, b"\x02", ((0, 1),), True, None, "", "B", 30_000_000),
                Read(90_000_000, 5, b"\x03", ((0, 2),), False, 91_000_000, "tx", "", 21_000_000)]
    line = reads_line([read_item(r, t0) for r in [*variants, reads[0]]])
    assert parse_reads(loads(line), t0) == [*variants, reads[0]]
