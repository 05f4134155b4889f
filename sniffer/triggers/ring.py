"""The last minutes of a capture, kept compactly for the windows a trigger opens.

Records are what a capture file holds, already encoded: each /raw event and each /frames record
(the bytes the MCAP sink writes), with the time that orders them and the message's log time.
They are packed into blocks of BLOCK_BYTES, each compressed with zstd once full (about a tenth
of the JSON), so five minutes of a busy 115200-baud line take a few MB.  Blocks wholly older
than `keep_ns` behind the newest time are dropped, and the oldest go whenever the compressed
blocks pass `max_bytes` (the byte bound wins: `cut_ns` then says from when the ring is whole).
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Iterator

import zstandard

RAW, RAW_CLEAN, FRAME = 0, 1, 2  # RAW_CLEAN: nothing was pending (framer, pairer) before it
BLOCK_BYTES = 128 * 1024
_REC = struct.Struct("<BqqI")  # kind, time, log time, length


class Block:
    __slots__ = ("lo", "hi", "data", "size")

    def __init__(self, lo: int, hi: int, data: bytes, size: int) -> None:
        self.lo, self.hi, self.data, self.size = lo, hi, data, size  # size: uncompressed


class Ring:
    def __init__(self, keep_ns: int, max_bytes: int) -> None:
        self.keep_ns = keep_ns
        self.max_bytes = max_bytes
        self.blocks: deque[Block] = deque()
        self.nbytes = 0  # compressed blocks
        self.cut_ns: int | None = None  # records before this may be gone for the byte bound
        self._open = bytearray()
        self._lo = self._hi = 0
        self._newest: int | None = None
        self._zc = zstandard.ZstdCompressor(level=1)
        self._zd = zstandard.ZstdDecompressor()

    def add(self, kind: int, t_ns: int, log_ns: int, data: bytes) -> None:
        buf = self._open
        if not buf:
            self._lo = self._hi = t_ns
        elif t_ns < self._lo:
            self._lo = t_ns
        elif t_ns > self._hi:
            self._hi = t_ns
        buf += _REC.pack(kind, t_ns, log_ns, len(data))
        buf += data
        if self._newest is None or t_ns > self._newest:
            self._newest = t_ns
        if len(buf) >= BLOCK_BYTES:
            self._seal()

    def _seal(self) -> None:
        raw = bytes(self._open)
        b = Block(self._lo, self._hi, self._zc.compress(raw), len(raw))
        self.blocks.append(b)
        self.nbytes += len(b.data)
        self._open = bytearray()
        self.trim()

    def trim(self) -> None:
        """Drop the blocks older than keep_ns behind the newest record, then down to max_bytes."""
        blocks = self.blocks
        if self._newest is not None:
            horizon = self._newest - self.keep_ns
            while blocks and blocks[0].hi < horizon:
                self.nbytes -= len(blocks.popleft().data)
        while blocks and self.nbytes > self.max_bytes:
            b = blocks.popleft()
            self.nbytes -= len(b.data)
            self.cut_ns = b.hi

    @property
    def first_ns(self) -> int | None:
        """The time of the oldest record held (None: empty)."""
        if self.blocks:
            return self.blocks[0].lo
        return self._lo if self._open else None

    def records(self, since_ns: int | None = None) -> Iterator[tuple[int, int, int, bytes]]:
        """(kind, time, log time, data) in the order added, skipping blocks wholly before since_ns."""
        for b in list(self.blocks):
            if since_ns is not None and b.hi < since_ns:
                continue
            yield from _unpack(self._zd.decompress(b.data, max_output_size=b.size))
        if self._open:
            yield from _unpack(bytes(self._open))


def _unpack(buf: bytes) -> Iterator[tuple[int, int, int, bytes]]:
    off, n, size = 0, len(buf), _REC.size
    view = memoryview(buf)
    while off < n:
        kind, t, log, length = _REC.unpack_from(buf, off)
        off += size
        yield kind, t, log, bytes(view[off:off + length])
        off += length


__all__ = ["BLOCK_BYTES", "FRAME", "RAW", "RAW_CLEAN", "Ring"]
