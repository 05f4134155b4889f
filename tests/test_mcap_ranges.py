"""formats/mcap/ranges.py reads a finished capture's summary itself (not the mcap library's get_summary, which
builds every chunk index's map of every channel): the index it gives is the one the library's summary gives."""

from __future__ import annotations

import glob
import os

import pytest

from sniffer.formats.mcap.format import RAW_TOPIC
from sniffer.formats.mcap.ranges import _INDEX_HEAD, raw_index

ROOT = os.path.join(os.path.dirname(__file__), "..", "captures")
CAPTURES = sorted(glob.glob(os.path.join(ROOT, "**", "*.mcap"), recursive=True))


def _by_the_library(path: str):
    """The index as the mcap library's summary gives it (what raw_index read before)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
        channel = next(c.id for c in summary.channels.values() if c.topic == RAW_TOPIC)
        chunks, total = [], 0
        for ci in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
            at = ci.message_index_offsets.get(channel)
            if at is None:
                continue
            fh.seek(at)
            _op, _length, _cid, size = _INDEX_HEAD.unpack(fh.read(_INDEX_HEAD.size))
            chunks.append((total, size // 16, ci.chunk_start_offset, ci.chunk_length, at))
            total += size // 16
        assert summary.statistics.channel_message_counts[channel] == total
        return channel, total, tuple(chunks)


@pytest.mark.parametrize("path", CAPTURES, ids=[os.path.basename(p) for p in CAPTURES])
def test_the_index_is_the_one_the_librarys_summary_gives(path):
    index = raw_index(path)
    assert index is not None and index.total > 0
    assert (index.channel, index.total, index.chunks) == _by_the_library(path)


def test_a_summary_that_fails_its_crc_is_not_read_by_number(tmp_path):
    path = CAPTURES[0]
    data = bytearray(open(path, "rb").read())
    with open(path, "rb") as fh:
        fh.seek(len(data) - 8 - 29 + 9)
        start = int.from_bytes(fh.read(8), "little")
    data[start + 20] ^= 0x01  # a byte of the summary's first record
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(data)
    assert raw_index(str(bad)) is None  # read in order (the reader) instead


def test_a_file_without_a_footer_is_not_read_by_number(tmp_path):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(open(CAPTURES[0], "rb").read()[:-100])
    assert raw_index(str(cut)) is None
