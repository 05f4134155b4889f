"""Reads as the port delivered them, each with the frames its bytes went to (the TUI's byte view).

A source hands the pipeline Chunks: one USB/serial read, or one run of bytes
of a logic analyzer (sniffer.events).  The framer cuts the byte stream into
frames, every byte into exactly one, in order, and frames reach the sinks in
that order; so counting bytes on both sides says where each frame begins
inside the reads.  `ReadMarker` is fed both (a sink's `raw()` and `frame()`,
in any interleaving) and, once every byte of a read is in a frame, gives the
`Read`: its time, its place in the stream, its bytes and its marks.  It is
sans-I/O (no threads, clocks or files); the TUI's sink and the publisher of
the viewers' stream (sinks/publish.py, stream_format.py) both run one.

Memory: a read waits only until its frames have settled (the pairer holds a
request until its answer: one transaction); who keeps reads afterwards keeps
a ring of the last RING_READS of them (tui/readring.py, the publisher's
backlog).
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass

from .events import Chunk

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


class ReadMarker:
    """Chunks and frames in, Reads with their marks out (see the module doc)."""

    def __init__(self) -> None:
        self.offset = 0  # bytes of the reads seen
        self.framed = 0  # bytes of the frames seen: the next frame begins here
        self._waiting: deque[tuple[Chunk, int]] = deque()  # reads whose bytes are not all framed yet
        self._starts: deque[tuple[int, int]] = deque()  # (stream offset, index) of frames not placed yet
        self._current: tuple[int, int] | None = None  # the last frame placed: (offset, index)

    def chunk(self, c: Chunk) -> list[Read]:
        if not c.data:
            return []
        self._waiting.append((c, self.offset))
        self.offset += len(c.data)
        return self._ready()

    def frame(self, index: int, size: int) -> list[Read]:
        """A settled frame of `size` bytes (frames come in stream order)."""
        self._starts.append((self.framed, index))
        self.framed += size
        return self._ready() if self._waiting else []

    def flush(self) -> list[Read]:
        """The end of the capture: every read goes out (a byte no frame took, which the pipeline never leaves,
        would count as the last frame's)."""
        out = self._ready()
        if self._waiting:
            self.framed = self.offset
            out += self._ready()
        return out

    def _ready(self) -> list[Read]:
        out = []
        waiting, starts = self._waiting, self._starts
        while waiting:
            c, off = waiting[0]
            end = off + len(c.data)
            if self.framed < end:
                break
            waiting.popleft()
            while starts and starts[0][0] <= off:
                self._current = starts.popleft()
            cur = self._current
            marks = [] if cur is None else [(0, cur[1])]
            cont = cur is not None and cur[0] < off
            while starts and starts[0][0] < end:
                self._current = s = starts.popleft()
                marks.append((s[0] - off, s[1]))
            out.append(Read(c.t_ns, off, c.data, tuple(marks), cont,
                            c.byte_t_ns[-1] if c.byte_t_ns else None, c.channel))
        return out
