"""A register's history over the whole capture: (time, value, frame number) samples in bounded memory.

Every numeric value the register watch shows is a sample (`Series.add`).  Up to
`cap` samples per register are kept as they came, in four `array` columns (t_ns,
value, frame index, flags: 25 bytes a sample).  The cap is 8,192 while there are
at most 128 registers; past that the registers share a budget of 2**20 samples
(26 MB), at least 1,024 each (`cap_for`: a capture of 644 registers keeps 1,628
samples a register).  When a register has more, the
history is thinned into time buckets (M4, as plotting libraries decimate a line):
of each bucket's samples it keeps

- the first,
- the first with the bucket's minimum and the first with its maximum,
- the one where the bucket's final value began (the last change),

so a plot of the thinned history, drawn as steps, has every bucket's extremes
and ends at each bucket's true value; a register that changes rarely keeps every
change at its own frame (up to three changes per bucket), and a constant one one
sample a bucket.  The first thinning makes buckets of the span so far / (cap / 8);
the next ones double the bucket width (merging pairs of buckets by the same rule),
so the whole capture stays evenly covered in at most `cap` samples.  With a `queue` (the register
book's: a block of 125 registers polled together reaches its cap together, and thinning 125
histories at once held the UI for 90 ms) a series over its cap queues itself and is thinned when
the book gets to it (`thin_queued`, a few per frame); past twice its cap it thins at once.  In the open
bucket (the latest) a sample is kept if its value changed, and the bucket is
reduced by the same rule every 32 samples and when the next one opens.

Flags: CHANGE (the value differs from the kept sample before it; the first
sample too) and GAP (value changes between the kept sample before it and this
one were thinned out).  The change log lists the samples with either flag.
"""

from __future__ import annotations

import bisect
from array import array

CAP = 8192  # samples kept per register at most (25 B each: 200 kB a register)
BUDGET = 1 << 20  # samples kept over all registers (26 MB): with more than 128 registers each keeps less
MIN_CAP = 1024  # ... but never less than this
OPEN = 32  # samples the open bucket may hold before it is reduced (reduced again as it closes)
CHANGE = 1
GAP = 2


def thin_queued(queue: list, n: int) -> None:
    """Thin up to n of the queued series (oldest first)."""
    for _ in range(min(n, len(queue))):
        queue.pop(0).thin_if_over()


def cap_for(registers: int, cap: int = CAP, budget: int = BUDGET) -> int:
    """The samples each of `registers` registers keeps: `cap`, less when the budget is shared by many."""
    return max(min(cap, budget // max(registers, 1)), min(MIN_CAP, cap))


class Series:
    """One register's samples (see the module doc)."""

    __slots__ = ("t", "v", "ix", "fl", "cap", "width", "origin", "bucket", "start", "seen", "changes", "last",
                 "t_end", "ix_end", "thins", "queue", "queued")

    def __init__(self, cap: int = CAP, queue: list | None = None) -> None:
        self.t = array("q")  # capture time, ns
        self.v = array("d")
        self.ix = array("q")  # Frame.index of the frame that brought the value
        self.fl = array("B")
        self.cap = max(cap, 16)
        self.width = 0  # bucket width in ns; 0: every sample kept
        self.origin = 0  # bucket 0 starts here
        self.bucket = -1  # the open bucket (the one new samples go to)
        self.start = 0  # position of the open bucket's first kept sample
        self.seen = 0  # samples added
        self.changes = -1  # value changes among them (the first value is not one: -1 before it)
        self.last = None  # the latest value
        self.t_end = 0  # the latest sample not kept (see `end`)
        self.ix_end = -1
        self.thins = 0  # times the history was thinned (views rebuild what they derived)
        self.queue = queue  # where a series over its cap waits to be thinned (None: thinned at once)
        self.queued = False

    # ------------------------------------------------------------ intake
    def add(self, t_ns: int, value, index: int) -> None:
        """A new sample (in arrival order).  The hot path of the register watch: kept short."""
        self.seen += 1
        w = self.width
        if value == self.last:
            if w and (t_ns - self.origin) // w <= self.bucket:  # unchanged in the open bucket: its kept
                self.t_end, self.ix_end = t_ns, index  # samples stand for it (a time going back stays in it)
                return
            flag = 0
        else:
            self.changes += 1
            self.last = value
            flag = CHANGE
        if w and (t_ns - self.origin) // w > self.bucket:  # a new bucket: the one before is reduced
            if len(self.v) - self.start > 4:
                self._reduce_open()
            self.bucket, self.start = (t_ns - self.origin) // w, len(self.v)
        self.t.append(t_ns)
        self.v.append(value)
        self.ix.append(index)
        self.fl.append(flag)
        if w and len(self.v) - self.start > OPEN:
            self._reduce_open()
        if len(self.v) > self.cap:
            self._over()

    def _over(self) -> None:
        q = self.queue
        if q is None or len(self.v) > 2 * self.cap:
            self._thin()
        elif not self.queued:
            self.queued = True
            q.append(self)

    def thin_if_over(self) -> None:
        """Thin if over the cap (a queued series, when its turn comes)."""
        self.queued = False
        if len(self.v) > self.cap:
            self._thin()

    def _reduce_open(self) -> None:
        """The open bucket's samples reduced to its first / min / max / start of the final value."""
        s = self.start
        group = _reduce(self.t[s:], self.v[s:], self.ix[s:], self.fl[s:], self.v[s - 1] if s else None)
        del self.t[s:], self.v[s:], self.ix[s:], self.fl[s:]
        for col, part in zip((self.t, self.v, self.ix, self.fl), group):
            col.extend(part)

    def _thin(self) -> None:
        """Too many samples: (wider) buckets, each reduced to its first / min / max / last change; the
        width doubles again while more than 3/4 of the cap remain (buckets of few samples keep them all)."""
        t = self.t
        if not self.width:
            self.origin = t[0]
            self.width = max(1, -(-(max(t[-1] - t[0], 1)) // max(self.cap // 8, 1)))
        else:
            self.width *= 2
        self.thins += 1
        self._rebucket()
        while len(self.t) > self.cap * 3 // 4:
            self.width *= 2
            self._rebucket()

    def _rebucket(self) -> None:
        t, v, ix, fl = self.t, self.v, self.ix, self.fl
        w, o = self.width, self.origin
        out = array("q"), array("d"), array("q"), array("B")
        n, i, start = len(t), 0, 0
        prev = None
        while i < n:
            b = (t[i] - o) // w
            j = max(bisect.bisect_left(t, o + (b + 1) * w, i), i + 1)  # the bucket's end (times ascend)
            start = len(out[0])
            group = (t[i:j], v[i:j], ix[i:j], fl[i:j]) if j - i == 1 else \
                _reduce(t[i:j], v[i:j], ix[i:j], fl[i:j], prev)
            for col, part in zip(out, group):
                col.extend(part)
            prev = out[1][-1]
            i = j
        self.t, self.v, self.ix, self.fl = out
        self.bucket = (t[-1] - o) // w
        self.start = start

    # ------------------------------------------------------------ reading
    def __len__(self) -> int:
        return len(self.v)

    def __iter__(self):
        return iter(self.v)

    def __getitem__(self, i):
        return self.v[i]

    @property
    def settled(self) -> int:
        """Samples before this position never change again until the next thinning (`thins`)."""
        return self.start if self.width else len(self.v)

    @property
    def end(self) -> tuple[int, int]:
        """(t_ns, frame index) of the latest sample, kept or not: where the line ends."""
        if self.t and self.t[-1] >= self.t_end:
            return self.t[-1], self.ix[-1]
        return self.t_end, self.ix_end

    def nearest(self, t_ns: float) -> tuple[int, float, int] | None:
        """(t_ns, value, frame index) of the kept sample nearest to t_ns (the latest sample counts too)."""
        t = self.t
        if not t:
            return None
        i = bisect.bisect_left(t, t_ns)
        best = None
        for j in (i - 1, i):
            if 0 <= j < len(t) and (best is None or abs(t[j] - t_ns) < abs(t[best] - t_ns)):
                best = j
        t_end, ix_end = self.end
        if abs(t_end - t_ns) < abs(t[best] - t_ns):
            return t_end, self.v[-1], ix_end
        return t[best], self.v[best], self.ix[best]

    def change_positions(self, start: int = 0) -> list[int]:
        """Positions (from `start` on) of the kept samples that are changes or follow thinned ones."""
        fl = self.fl
        return [i for i in range(start, len(fl)) if fl[i]]

    def change(self, pos: int) -> tuple[int, int, float | None, float, bool]:
        """(t_ns, frame index, old value or None for the first, new value, changes thinned before it)."""
        return self.t[pos], self.ix[pos], self.v[pos - 1] if pos else None, self.v[pos], bool(self.fl[pos] & GAP)


def _reduce(ts, vs, ixs, fls, prev) -> tuple:
    """One bucket's samples reduced to the first, the first minimum, the first maximum and the start of
    the final value, flags made relative to what is kept: CHANGE where the value differs from the kept
    sample before, GAP where a dropped sample between them was a change (or followed one dropped earlier).
    `prev` is the value of the kept sample before the bucket (None: there is none)."""
    final = max(len(fls.tobytes().rstrip(b"\0")) - 1, 0)  # unchanged samples at the end: where it began
    out = array("q"), array("d"), array("q"), array("B")
    last = -1
    for i in sorted({0, vs.index(min(vs)), vs.index(max(vs)), final}):
        gap = fls[i] & GAP or i - last > 1 and any(fls[last + 1:i])
        flag = (CHANGE if prev is None or vs[i] != prev else 0) | (GAP if gap else 0)
        for col, x in zip(out, (ts[i], vs[i], ixs[i], flag)):
            col.append(x)
        prev, last = vs[i], i
    return out
