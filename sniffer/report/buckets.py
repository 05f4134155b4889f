"""Counts over time in bounded memory: at most `n` buckets of equal width, the width doubling as the capture grows.

    b = TimeBuckets(("frames", "crc"))
    i = b.index(x_ns)          # the bucket of a time on the report's axis (ns from its start)
    b.cols["frames"][i] += 1
    b.to_dict(end_ns)          # {"width_s", "x": bucket starts in s, "frames": [...], ...}

When a time falls past the last bucket, neighbouring buckets are merged in pairs
(their counts added) and the width doubles, so a million-frame capture of a day and
one of ten seconds both end in at most `n` buckets that cover them evenly, and every
count is kept (the sum of a column never changes by a merge).
"""

from __future__ import annotations

from array import array

MAX_BUCKETS = 1024
FIRST_WIDTH_NS = 100_000_000  # 0.1 s: a short capture keeps this resolution


class TimeBuckets:
    """Columns of per-bucket sums (see the module doc)."""

    def __init__(self, columns, n: int = MAX_BUCKETS, width_ns: int = FIRST_WIDTH_NS) -> None:
        self.n = max(2, n - n % 2)
        self.width = max(1, width_ns)
        self.cols: dict[str, array] = {c: array("d", bytes(8 * self.n)) for c in columns}
        self.top = -1  # the last bucket used

    def index(self, x_ns: int) -> int:
        """The bucket of time x_ns (ns from the report's start; earlier times count in the first)."""
        b = x_ns // self.width if x_ns > 0 else 0
        while b >= self.n:
            self._merge()
            b = x_ns // self.width
        if b > self.top:
            self.top = b
        return b

    def _merge(self) -> None:
        """Pairs of buckets become one of twice the width."""
        half = self.n // 2
        for col in self.cols.values():  # in place: a column read before index() is still the column
            for i in range(half):
                col[i] = col[2 * i] + col[2 * i + 1]
            col[half:] = array("d", bytes(8 * half))
        self.width *= 2
        self.top //= 2

    def total(self, column: str) -> float:
        return sum(self.cols[column])

    def to_dict(self, end_ns: int | None = None) -> dict:
        """Bucket starts (s) and each column up to the last bucket used; `span_s`: each bucket's time that lies
        before `end_ns` (the last bucket of a capture is partly after its end)."""
        k = self.top + 1
        w = self.width
        out = {"width_s": w / 1e9, "x": [i * w / 1e9 for i in range(k)]}
        for name, col in self.cols.items():
            out[name] = [round(v, 6) for v in col[:k]]
        if end_ns is not None:
            out["span_s"] = [max(min(w, end_ns - i * w), 0) / 1e9 for i in range(k)]
        return out
