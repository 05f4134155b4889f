"""The byte view's model: the last reads of the capture, and where a frame's bytes are among them (no Textual).

A ring of at most RING_READS reads holding at most RING_BYTES bytes
(sniffer.analysis.reads): older reads are dropped a quarter at a time, so appending
stays cheap and memory stays flat however long the capture runs.  Reads are
in stream order and so are the frames their bytes went to, which lets
`find(index)` bisect for the read holding a frame's first byte.  Positions
are `seq` numbers counted from the first read ever added, so they stay valid
while older reads are dropped (`first_seq` is the oldest still here).
"""

from __future__ import annotations

import bisect
from array import array

from sniffer.analysis.reads import RING_BYTES, RING_READS, Read


class ReadRing:
    def __init__(self, limit: int = RING_READS, max_bytes: int = RING_BYTES) -> None:
        self.limit = max(limit, 4)
        self.max_bytes = max_bytes
        self.reads: list[Read] = []
        self.first_frame = array("q")  # per read: the frame its first byte went to (-1: none)
        self.last_frame = array("q")  # per read: the frame its last byte went to
        self.first_seq = 0  # seq of reads[0]
        self.size = 0  # bytes held
        self.generation = 0  # bumped on every change

    def __len__(self) -> int:
        return len(self.reads)

    @property
    def end_seq(self) -> int:
        return self.first_seq + len(self.reads)

    def get(self, seq: int) -> Read | None:
        i = seq - self.first_seq
        return self.reads[i] if 0 <= i < len(self.reads) else None

    def add(self, reads) -> int:
        """Append reads (in stream order); returns how many older ones were dropped to make room."""
        n = 0
        for r in reads:
            self.reads.append(r)
            self.first_frame.append(r.marks[0][1] if r.marks else -1)
            self.last_frame.append(r.marks[-1][1] if r.marks else -1)
            self.size += len(r.data)
            n += 1
        if not n:
            return 0
        self.generation += 1
        reads = self.reads
        drop = len(reads) - self.limit + self.limit // 4 if len(reads) > self.limit else 0
        gone = sum(len(r.data) for r in reads[:drop])
        if self.size - gone > self.max_bytes:  # too many bytes: down to three quarters of the limit
            while drop < len(reads) - 1 and self.size - gone > self.max_bytes * 3 // 4:
                gone += len(reads[drop].data)
                drop += 1
        if drop > 0:
            self.size -= gone
            del reads[:drop]
            del self.first_frame[:drop]
            del self.last_frame[:drop]
            self.first_seq += drop
        return drop

    def find(self, index: int) -> int | None:
        """The seq of the read holding frame `index`'s first byte, or None (older than the ring, or none)."""
        ff = self.first_frame
        i = bisect.bisect_right(ff, index) - 1
        if i < 0 or self.last_frame[i] < index:
            return None
        while i > 0 and ff[i] == index and self.reads[i].cont:  # it began in an earlier read
            i -= 1
        return self.first_seq + i

    def frames_between(self, seq: int, index: int, forward: bool) -> int | None:
        """The frame after (before) `index` among the reads, looking from read `seq` on; None at the ends."""
        r = self.get(seq)
        if r is None:
            return None
        step = 1 if forward else -1
        while r is not None:
            cands = [i for i in r.frames if (i > index if forward else i < index)]
            if cands:
                return min(cands) if forward else max(cands)
            seq += step
            r = self.get(seq)
        return None
