"""Reads as the port delivered them, each with the frames its bytes went to (the TUI's byte view).

A source hands the pipeline Chunks: one USB/serial read, or one run of bytes
of a logic analyzer (sniffer.events).  The framer cuts the byte stream into
frames, every byte into exactly one, in order, and frames reach the sinks in
that order; so counting bytes on both sides says where each frame begins
inside the reads.  `ReadMarker` is fed both (a sink's `raw()` and `frame()`,
in any interleaving) and, once every byte of a read is in a frame, gives the
`Read`: its time, its place in the stream, its bytes and its marks.  It is
sans-I/O (no threads, clocks or files); the TUI's sink and the publisher of
the viewers' stream (processes/publish_sink.py, processes/stream.py) both run one.

Several links (sniffer.capture.links): every link is a byte stream of its own, cut into
frames by its own framer, so frames are counted against the reads of their own
link (`frame(index, size, link)`); reads still come out in the order they were
read (a read waits for the reads before it, of every link), `offset` counting
the bytes of every link before it, and each says its `link`.

Memory: a read waits only until its frames have settled (the pairer holds a
request until its answer: one transaction); who keeps reads afterwards keeps
a ring of the last RING_READS of them (tui/readring.py, the publisher's
backlog).
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

from sniffer.events import Chunk

RING_READS = 10_000  # reads a viewer keeps (and a publisher keeps for viewers that join late)
RING_BYTES = 1 << 20  # ... and at most this many of their bytes


@dataclass(slots=True)
class Read:  # not frozen: 2.5 times quicker to make (the capture thread makes one per read); never changed
    """One read.  `marks`: (position in `data`, frame index) of the frame its first byte went to (position 0)
    and of every frame that begins later in it; `cont`: byte 0 continues a frame begun in an earlier read."""

    t_ns: int  # per read: when the read returned; per byte: its first byte's start
    offset: int  # bytes of the capture before this read
    data: bytes
    marks: tuple[tuple[int, int], ...]
    cont: bool = False
    last_ns: int | None = None  # per byte: its last byte's start; None: one time for the read
    channel: str = ""
    link: str = ""  # the link it was read on, in a capture of several links
    # the live reader stalled before it (Chunk.unseen_ns): the port went unseen this long before t_ns, so the
    # bytes came somewhere within it, and the gap since the previous read is not a measured silence
    unseen_ns: int | None = None

    @property
    def per_byte(self) -> bool:
        return self.last_ns is not None

    @property
    def frames(self) -> tuple[int, ...]:
        """The frames its bytes went to, in order."""
        return tuple(i for _, i in self.marks)

    def starts(self) -> frozenset[int]:
        """Positions in `data` where a frame begins."""
        return frozenset(p for p, _ in self.marks if p or not self.cont)

    def frame_at(self, pos: int) -> int | None:
        """The frame byte `pos` went to."""
        m = self.marks
        if not m:
            return None
        return m[bisect.bisect_right(m, (pos, float("inf"))) - 1][1]

    def span_of(self, index: int) -> tuple[int, int] | None:
        """[start, end) of frame `index`'s bytes in this read."""
        m = self.marks
        for k, (p, i) in enumerate(m):
            if i == index:
                return p, m[k + 1][0] if k + 1 < len(m) else len(self.data)
        return None


class _Stream:
    """One link's byte stream: its bytes read, its bytes framed, its frames not placed yet."""

    __slots__ = ("current", "framed", "offset", "starts")

    def __init__(self) -> None:
        self.offset = 0  # bytes of the reads seen
        self.framed = 0  # bytes of the frames seen: the next frame begins here
        self.starts: deque[tuple[int, int]] = deque()  # (stream offset, index) of frames not placed yet
        self.current: tuple[int, int] | None = None  # the last frame placed: (offset, index)


class ReadMarker:
    """Chunks and frames in, Reads with their marks out (see the module doc)."""

    def __init__(self) -> None:
        self.offset = 0  # bytes of the reads seen (every link's)
        self._streams: dict[str, _Stream] = {"": _Stream()}
        # reads whose bytes are not all framed yet (or behind one that is not): (chunk, offset, link's offset)
        self._waiting: deque[tuple[Chunk, int, int]] = deque()

    @property
    def framed(self) -> int:
        """Bytes of the frames seen (every link's)."""
        return sum(s.framed for s in self._streams.values())

    def _stream(self, link: str) -> _Stream:
        s = self._streams.get(link)
        if s is None:
            s = self._streams[link] = _Stream()
        return s

    def chunk(self, c: Chunk) -> list[Read]:
        if not c.data:
            return []
        s = self._stream(c.link)
        self._waiting.append((c, self.offset, s.offset))
        self.offset += len(c.data)
        s.offset += len(c.data)
        return self._ready()

    def frame(self, index: int, size: int, link: str = "") -> list[Read]:
        """A settled frame of `size` bytes of `link` (a link's frames come in its stream's order)."""
        s = self._stream(link)
        s.starts.append((s.framed, index))
        s.framed += size
        return self._ready() if self._waiting else []

    def flush(self) -> list[Read]:
        """The end of the capture: every read goes out (a byte no frame took, which the pipeline never leaves,
        would count as the last frame's)."""
        out = self._ready()
        if self._waiting:
            for s in self._streams.values():
                s.framed = s.offset
            out += self._ready()
        return out

    def _ready(self) -> list[Read]:
        out = []
        waiting, streams = self._waiting, self._streams
        while waiting:
            c, off, loff = waiting[0]
            st = streams[c.link]
            end = loff + len(c.data)
            if st.framed < end:
                break
            waiting.popleft()
            starts = st.starts
            while starts and starts[0][0] <= loff:
                st.current = starts.popleft()
            cur = st.current
            marks = [] if cur is None else [(0, cur[1])]
            cont = cur is not None and cur[0] < loff
            while starts and starts[0][0] < end:
                st.current = s = starts.popleft()
                marks.append((s[0] - loff, s[1]))
            out.append(Read(c.t_ns, off, c.data, tuple(marks), cont,
                            c.byte_t_ns[-1] if c.byte_t_ns else None, c.channel, c.link, c.unseen_ns))
        return out
