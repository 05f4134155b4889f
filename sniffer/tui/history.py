"""A register's history over the whole capture: (time, value, frame number) samples in bounded memory.

Every numeric value the register watch shows is a sample (`Series.add`).  Up to
`cap` samples per register are kept as they came, in four `array` columns (t_ns,
value, frame index, flags: 25 bytes a sample).  When a register has more, the
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
so the whole capture stays evenly covered in at most `cap` samples.  New samples
land in the open bucket by the same rule as they arrive.

Flags: CHANGE (the value differs from the kept sample before it; the first
sample too) and GAP (value changes between the kept sample before it and this
one were thinned out).  The change log lists the samples with either flag.
"""

from __future__ import annotations

import bisect
from array import array

CAP = 8192  # samples kept per register (25 B each: at most 200 kB a register)
CHANGE = 1
GAP = 2


class Series:
    """One register's samples (see the module doc)."""

    __slots__ = ("t", "v", "ix", "fl", "cap", "width", "origin", "bucket", "start", "seen", "changes", "last",
                 "t_end", "ix_end", "thins")

    def __init__(self, cap: int = CAP) -> None:
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
        self.changes = 0  # value changes among them (the first value is not one)
        self.last = None  # the latest value
        self.t_end = 0  # the latest sample (kept or not): where the line ends
        self.ix_end = -1
        self.thins = 0  # times the history was thinned (views rebuild what they derived)

    # ------------------------------------------------------------ intake
    def add(self, t_ns: int, value, index: int) -> None:
        """A new sample (in arrival order)."""
        self.t_end, self.ix_end = t_ns, index
        seen = self.seen
        self.seen = seen + 1
        changed = not seen or value != self.last
        if changed:
            if seen:
                self.changes += 1
            self.last = value
        w = self.width
        if not w:
            self.t.append(t_ns)
            self.v.append(value)
            self.ix.append(index)
            self.fl.append(CHANGE if changed else 0)
        else:
            b = max((t_ns - self.origin) // w, self.bucket)  # a time going back stays in the open bucket
            if b != self.bucket:
                self.bucket, self.start = b, len(self.t)
                self.t.append(t_ns)
                self.v.append(value)
                self.ix.append(index)
                self.fl.append(CHANGE if changed else 0)
            elif changed:
                s, vs = self.start, self.v
                last = len(vs) - 1
                lo, hi = min(vs[s:]), max(vs[s:])
                if lo < value < hi:  # not an extreme: it becomes the bucket's final value
                    if last == s or vs.index(lo, s) == last or vs.index(hi, s) == last:
                        self.t.append(t_ns)  # the final value so far is an extreme or the first: kept
                        vs.append(value)
                        self.ix.append(index)
                        self.fl.append(CHANGE)
                        if len(vs) > self.cap:
                            self._thin()
                        return
                    # the final value so far was neither: this one takes its place
                    self.t[last], self.ix[last] = t_ns, index
                    self.fl[last] = (CHANGE if value != vs[last - 1] else 0) | GAP
                    vs[last] = value
                    return
                # a new extreme: the bucket's kept samples and this one, reduced again
                group = _reduce(self.t[s:], self.v[s:], self.ix[s:], self.fl[s:] + array("B", [CHANGE]),
                                t_ns, value, index, self.v[s - 1] if s else None)
                del self.t[s:], self.v[s:], self.ix[s:], self.fl[s:]
                self._extend(group)
            else:  # unchanged: the bucket's kept samples stand for it
                return
        if len(self.t) > self.cap:
            self._thin()

    def _extend(self, group) -> None:
        t, v, ix, fl = group
        self.t.extend(t)
        self.v.extend(v)
        self.ix.extend(ix)
        self.fl.extend(fl)

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
        t = self.t
        w, o = self.width, self.origin
        v, ix, fl = self.v, self.ix, self.fl
        out = array("q"), array("d"), array("q"), array("B")
        n, i, start = len(t), 0, 0
        prev = None
        while i < n:
            b = (t[i] - o) // w
            j = i + 1
            while j < n and (t[j] - o) // w <= b:
                j += 1
            start = len(out[0])
            if j - i == 1:  # alone in its bucket: kept as it is
                group = t[i:j], v[i:j], ix[i:j], fl[i:j]
            else:
                group = _reduce(t[i:j - 1], v[i:j - 1], ix[i:j - 1], fl[i:j], t[j - 1], v[j - 1], ix[j - 1], prev)
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
        if abs(self.t_end - t_ns) < abs(t[best] - t_ns):
            return self.t_end, self.v[-1], self.ix_end
        return t[best], self.v[best], self.ix[best]

    def change_positions(self, start: int = 0) -> list[int]:
        """Positions (from `start` on) of the kept samples that are changes or follow thinned ones."""
        fl = self.fl
        return [i for i in range(start, len(fl)) if fl[i]]

    def change(self, pos: int) -> tuple[int, int, float | None, float, bool]:
        """(t_ns, frame index, old value or None for the first, new value, changes thinned before it)."""
        return self.t[pos], self.ix[pos], self.v[pos - 1] if pos else None, self.v[pos], bool(self.fl[pos] & GAP)


def _reduce(ts, vs, ixs, fls, t_new, v_new, ix_new, prev) -> tuple:
    """One bucket's samples (the arrays, then the last sample on its own; fls includes its flags)
    reduced to first / min / max / start of the final value, flags made relative to what is kept.
    `prev` is the value of the kept sample before the bucket (None: there is none)."""
    ts, vs, ixs = list(ts) + [t_new], list(vs) + [v_new], list(ixs) + [ix_new]
    n = len(vs)
    final = n - 1
    while final > 0 and not fls[final]:  # unchanged samples at the end: the final value began earlier
        final -= 1
    keep = sorted({0, vs.index(min(vs)), vs.index(max(vs)), final})
    out = [], [], [], []
    gap = False
    k = 0
    for i in range(n):
        if k < len(keep) and keep[k] == i:
            k += 1
            flag = (CHANGE if prev is None or vs[i] != prev else 0) | (GAP if gap or fls[i] & GAP else 0)
            for col, x in zip(out, (ts[i], vs[i], ixs[i], flag)):
                col.append(x)
            prev, gap = vs[i], False
        elif fls[i]:
            gap = True
    return out
