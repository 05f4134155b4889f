"""Response latency per unit: a histogram in log-ish bins, exact median / p95 / p99 / max, unanswered counts.

Textual-free (rich only, for the drawing).  `LatencyStats.add` is O(1) per response, called as
frames arrive; the percentiles sort lazily, only when someone draws them, merging the values
that came since the last time into the sorted ones (two sorted runs: timsort merges them in
linear time), so a live capture never re-sorts the world per tick.

Percentiles are by the nearest rank: the p-th percentile of n sorted values is the value at
rank ceil(p * n / 100) (the median of an even count is the lower middle value).
"""

from __future__ import annotations

import bisect
from array import array

from rich.text import Text

# bin upper edges in ms, 1-2-5 steps over 0.5..1000 ms; a bin holds (previous edge, edge]; one more past 1000
EDGES_MS = (0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)
BIN_LABELS = tuple(f"≤{e:g}" for e in EDGES_MS) + (f">{EDGES_MS[-1]:g}",)
_BLOCKS = " ▁▂▃▄▅▆▇█"  # eighths of a character cell
BAR_ROWS = 5
COL = 6  # characters per bin column (12 bins and the labels fit 80 columns)
_LEFT = 3  # the label column


def bin_of(ms: float) -> int:
    """The bin a latency falls in (0 .. len(EDGES_MS))."""
    return bisect.bisect_left(EDGES_MS, ms)


def nearest_rank(sorted_values, pct: int) -> float:
    """The pct-th percentile (integer pct, 1..100) of ascending values, by the nearest rank."""
    n = len(sorted_values)
    return sorted_values[max((pct * n + 99) // 100 - 1, 0)]


class LatencyStats:
    """One unit's (or every unit's) latencies and unanswered requests."""

    __slots__ = ("_new", "_sorted", "bins", "end_of_capture", "no_response", "timeouts", "unmeasured")

    def __init__(self) -> None:
        self.bins = [0] * (len(EDGES_MS) + 1)
        self._sorted = array("d")
        self._new = array("d")
        self.timeouts = 0  # requests the pairer gave up on past the unit's timeout (pair.timeout)
        self.no_response = 0  # requests followed by the next one before the timeout (pair.no_response only)
        self.end_of_capture = 0  # the capture ended while waiting
        self.unmeasured = 0  # answered, but no latency (the response came in the request's USB read)

    def add(self, ms: float) -> None:
        self.bins[bin_of(ms)] += 1
        self._new.append(ms)

    @property
    def count(self) -> int:
        return len(self._sorted) + len(self._new)

    def sorted_values(self) -> array:
        if self._new:
            self._sorted = array("d", sorted(self._sorted.tolist() + sorted(self._new)))
            self._new = array("d")
        return self._sorted

    def figures(self) -> dict | None:
        """{n, median, p95, p99, max} in ms, or None without a latency."""
        s = self.sorted_values()
        if not s:
            return None
        return {"n": len(s), "median": nearest_rank(s, 50), "p95": nearest_rank(s, 95),
                "p99": nearest_rank(s, 99), "max": s[-1]}


def _ms(v: float) -> str:
    return f"{v:.1f}" if v >= 10 else f"{v:.2f}"


def _count(n: int) -> str:
    return str(n) if n < 100_000 else f"{n // 1000}k"


def figures_line(st: LatencyStats) -> str:
    fig = st.figures()
    if fig is None:
        return "no latency measured"
    return (f"n {fig['n']}  median {_ms(fig['median'])}  p95 {_ms(fig['p95'])}  p99 {_ms(fig['p99'])}  "
            f"max {_ms(fig['max'])} ms")


def unanswered_line(st: LatencyStats) -> str:
    parts = [f"timeouts {st.timeouts}", f"no response {st.no_response}"]
    if st.end_of_capture:
        parts.append(f"unanswered at the end {st.end_of_capture}")
    if st.unmeasured:
        parts.append(f"no latency {st.unmeasured} (read with their request)")
    return "  ".join(parts)


def histogram_text(st: LatencyStats, title: str, bar_rows: int = BAR_ROWS) -> Text:
    """Title and figures, the unanswered counts, then a column of block characters per bin, its label, its count."""
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append(f"{title}: ", "bold")
    text.append(figures_line(st) + "\n")
    text.append(unanswered_line(st) + "\n", "yellow" if st.timeouts or st.no_response else "dim")
    top = max(st.bins) or 1
    levels = [0 if c == 0 else max(1, round(c * bar_rows * 8 / top)) for c in st.bins]
    pad = " " * _LEFT
    for r in range(bar_rows, 0, -1):  # the top row first
        line = "".join(_BLOCKS[min(max(lv - (r - 1) * 8, 0), 8)] * (COL - 1) + " " for lv in levels)
        text.append(f"{pad}{line}\n", "cyan")
    text.append(f"{'ms':>{_LEFT - 1}} " + "".join(f"{lab:<{COL}}" for lab in BIN_LABELS) + "\n", "dim")
    text.append(f"{'n':>{_LEFT - 1}} " + "".join(f"{_count(c):<{COL}}" for c in st.bins))
    return text
