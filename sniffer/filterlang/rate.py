"""`rate(EXPR) > 5/min`: how many frames matching EXPR fell in a sliding window of capture time.

    rate(crc) > 5/min            more than 5 frames with a bad CRC in the last minute
    rate(timeout u:3) >= 3/10s   at least 3 timeouts of unit 3 within 10 seconds
    rate(exc) < 1/h              no exception for an hour (a frame passes while that holds)

The value is a count over a window: `N/W` where W is a time (s, min, h, a bare unit is one of it;
10min, 30s), at most 24 h.  A frame at time t passes when the count of frames matching EXPR in
(t - W, t] (itself included) compares with N as the operator says.  The count is of every frame
before it in the capture, whatever else the filter says: `u:1 rate(crc) > 5/min` is unit 1's frames
while the line as a whole has more than 5 CRC errors a minute.  EXPR is any filter without a rate.

On a stream (a capture trigger: `Query.matches` called on every frame in order) each Rate keeps its
matching frames' times (`SlidingCount`); on a store (the TUI) `Rate.rows` counts from the columns.
"""

from __future__ import annotations

from bisect import bisect_right, insort
from dataclasses import dataclass

from sniffer.filterlang.facts import Facts
from sniffer.filterlang.nodes import Node
from sniffer.filterlang.values import BadValue, Interval, comparison_intervals, parse_duration, parse_number

MAX_WINDOW_NS = 24 * 3600 * 10**9
LATE_NS = 10 * 10**9  # a frame may reach the filter this much after a later one (the pairer holds requests)


def parse_per(text: str) -> tuple[float, int]:
    """(count, window ns) of `5/min`, `20/10min`, `0.5/s`; BadValue (with the offset) otherwise."""
    n_text, sep, w_text = text.partition("/")
    got = parse_number(n_text) if n_text else None
    if not sep or got is None or got[1] or got[0] < 0:
        raise BadValue(f"a rate is a count per time: 5/min, 20/10min, 1/h (not {text!r})")
    if w_text and not w_text[0].isdigit() and w_text[0] != ".":
        w_text = "1" + w_text  # /min is one minute
    try:
        window = parse_duration(w_text, "s") if w_text else 0
    except BadValue as e:
        raise BadValue(str(e), len(n_text) + 1) from None
    if not 0 < window <= MAX_WINDOW_NS:
        raise BadValue(f"a rate's time is more than 0 and at most 24h, not {w_text!r}", len(n_text) + 1)
    return got[0], int(window)


@dataclass(frozen=True)
class Rate(Node):
    src: str
    item: Node
    op: str
    count: float
    window_ns: int
    spans: tuple[Interval, ...]

    cost = 9

    def passes(self, n: int) -> bool:
        if self.op == "!=":
            return n != self.count
        return any(n in iv for iv in self.spans)

    def test(self, fx) -> bool:
        """What the stream (Query.matches) or the store (Query.rows) worked out for this frame."""
        rates = fx.rates
        return bool(rates) and rates.get(self, False)

    def match_times(self, cols, end: int) -> list[int]:
        """The times of the rows 0..end-1 that match EXPR, ascending."""
        sure, maybe = self.item.rows(cols, range(end))
        if maybe:
            item, flags = self.item, cols.flags
            sure |= {r for r in maybe if item.test(Facts(cols.peek(r), cols, flags[r]))}
        t = cols.t_ns
        return sorted(t[r] for r in sure)

    def rows(self, cols, cand):
        cand = cand if isinstance(cand, range) else sorted(cand)
        if not cand:
            return set(), set()
        times = self.match_times(cols, cand[-1] + 1)
        t, w, passes = cols.t_ns, self.window_ns, self.passes
        return {r for r in cand if passes(bisect_right(times, t[r]) - bisect_right(times, t[r] - w))}, set()

    def __str__(self) -> str:
        return self.src


def rate_terms(node: Node | None) -> list[Rate]:
    """The Rate terms of a tree (in order)."""
    out: list[Rate] = []

    def walk(n):
        if isinstance(n, Rate):
            out.append(n)
            return
        for child in getattr(n, "items", ()) or ((n.item,) if hasattr(n, "item") else ()):
            walk(child)

    if node is not None:
        walk(node)
    return out


class SlidingCount:
    """The times of matching frames within a window behind the newest; count(t) over (t - W, t]."""

    def __init__(self, window_ns: int) -> None:
        self.window_ns = window_ns
        self.times: list[int] = []
        self.lo = 0  # times[:lo] are out of every window still asked about

    def add(self, t: int) -> None:
        times = self.times
        if not times or t >= times[-1]:
            times.append(t)
        else:
            insort(times, t, lo=self.lo)

    def count(self, t: int) -> int:
        times = self.times
        if not times:
            return 0
        lo = self.lo = bisect_right(times, times[-1] - self.window_ns - LATE_NS, lo=self.lo)
        if lo > 4096 and lo * 2 > len(times):
            del times[:lo]
            self.lo = lo = 0
        return bisect_right(times, t, lo=lo) - bisect_right(times, t - self.window_ns, lo=lo)

    def seed(self, times: list[int]) -> None:
        """Start from these times (ascending): a store's rows before the stream goes on."""
        self.times = list(times[bisect_right(times, times[-1] - self.window_ns - LATE_NS):]) if times else []
        self.lo = 0


def make_rate(src: str, item: Node, op: str, per: str) -> Rate:
    count, window = parse_per(per)
    return Rate(src, item, op, count, window, comparison_intervals(op, count) if op != "~" else ())


__all__ = ["MAX_WINDOW_NS", "Rate", "SlidingCount", "make_rate", "parse_per", "rate_terms"]
