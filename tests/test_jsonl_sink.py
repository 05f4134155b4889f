"""JsonlSink: lines joined in batches for files and pipes, one by one when each must reach its reader."""

from __future__ import annotations

import io

import orjson

from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.formats.jsonl import BATCH, JsonlSink


def _frames(n: int):
    for i in range(n):
        f = Frame(i, i * 1000, i * 1000 + 500, bytes([1, 3, i & 0xFF]), "modbus-rtu", 1, 3, 1, True)
        f.summary = f"frame {i}"
        yield f


def _lines(buf: io.BytesIO) -> list[dict]:
    return [orjson.loads(x) for x in buf.getvalue().splitlines()]


def test_batched_lines_arrive_whole_and_in_order_by_close():
    buf = io.BytesIO()
    sink = JsonlSink(buf)
    sink.start(CaptureInfo())
    n = BATCH * 2 + 7
    for k, f in enumerate(_frames(n), 1):
        sink.frame(f)
        assert len(_lines(buf)) == k - k % BATCH  # whole batches only, never a cut line
    sink.close()
    assert [r["index"] for r in _lines(buf)] == list(range(n))
    assert buf.getvalue().endswith(b"\n")


def test_flushed_sink_writes_each_line_as_its_frame_settles():
    buf = io.BytesIO()
    sink = JsonlSink(buf, flush=True)
    sink.start(CaptureInfo())
    for k, f in enumerate(_frames(5), 1):
        sink.frame(f)
        assert [r["summary"] for r in _lines(buf)] == [f"frame {i}" for i in range(k)]
    sink.close()


def test_text_lines_are_batched_too_and_a_viewer_flush_writes_them():
    from sniffer.formats.text import TextSink, frame_line

    buf = io.StringIO()
    sink = TextSink(buf)
    sink.start(CaptureInfo())
    frames = list(_frames(3))
    for f in frames:
        sink.frame(f)
    assert buf.getvalue() == ""  # held for one write
    sink.flush()  # what `sniffer attach` does after each batch it receives
    assert buf.getvalue().splitlines() == [frame_line(f, 0) for f in frames]
    sink.frame(frames[0])
    sink.close()
    assert buf.getvalue().splitlines()[-1] == frame_line(frames[0], 0)
