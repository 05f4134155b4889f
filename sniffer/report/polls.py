"""Poll cycles: per request type (unit, function, first register, count: `analysis.diff.request_key`), the time
from one request of that type to the next, i.e. the period the master polls it at, and how much it wanders.

Per type a count, the gap's percentiles (`analysis.diff.Quantiles`: bounded), its mean and standard deviation
(Welford), and the gaps over time (`analysis.history.Series`, thinned).  Jitter is shown as p95 - p5 of the
gaps (a retry or a skipped cycle is an outlier it does not hide behind) and as the standard deviation.
At most MAX_TYPES types are followed; requests of types beyond are counted, not timed.
"""

from __future__ import annotations

import math

from sniffer.protocols import of_frame
from sniffer.analysis.diff import Quantiles, key_text, request_key
from sniffer.analysis.history import Series
from sniffer.report.units import series_points

MAX_TYPES = 512
GAP_POINTS = 1024  # kept per type for the plot
PLOTTED = 12  # the most frequent types get a line in the plot


def request_type(f) -> tuple:
    """A request's type: a Modbus request by function, first register and count; another protocol's
    (PD-series: ADDR FUNC LEN DATA) by function and its first data byte (the parameter or status selector).
    With several links a unit is its link's: (link, unit, ...)."""
    proto = of_frame(f.protocol)
    if proto is None or proto.family == "modbus":
        return (f.link, f.unit, *request_key(f))
    adu = f.adu
    return f.link, f.unit, f.function, "sel", adu[3] if len(adu) > 3 else None


def type_label(f, key: tuple) -> str:
    """'u3 fc03 holding 0..9 (10)' ("LINK:u3 ..." with several links); another protocol's type is named by the
    summary of its first request."""
    who = f"{f.link}:u{f.unit}" if f.link else f"u{f.unit}"
    if key[3] == "sel":
        return f"{who} fc{f.function:02X} {f.summary.split(' = ')[0][:60]}"
    return f"{who} {key_text(key[2:])}"


class PollType:
    __slots__ = ("key", "count", "last_ns", "gaps", "mean", "m2", "lo", "hi", "series", "label")

    def __init__(self, key: tuple, t_ns: int, label: str) -> None:
        self.key = key
        self.label = label
        self.count = 1
        self.last_ns = t_ns
        self.gaps = Quantiles()
        self.mean = self.m2 = 0.0
        self.lo = self.hi = None
        self.series = Series(GAP_POINTS)

    def add(self, t_ns: int, index: int) -> None:
        self.count += 1
        last, self.last_ns = self.last_ns, t_ns
        if last is None:  # the first of a capture: the time since the capture before is no period
            return
        ms = (t_ns - last) / 1e6
        self.gaps.add(ms)
        n = self.gaps.n
        d = ms - self.mean
        self.mean += d / n
        self.m2 += d * (ms - self.mean)
        self.lo = ms if self.lo is None or ms < self.lo else self.lo
        self.hi = ms if self.hi is None or ms > self.hi else self.hi
        self.series.add(t_ns, ms, index)

    def row(self) -> dict:
        g = self.gaps
        p5, p50, p95 = g.pct(0.05), g.median(), g.pct(0.95)
        link, unit = self.key[:2]
        return {"type": self.label, "unit": f"{link}:{unit}" if link else str(unit), "count": self.count,
                "period_ms": None if p50 is None else round(p50, 3), "p5_ms": p5, "p95_ms": p95,
                "jitter_ms": None if p5 is None else round(p95 - p5, 3),
                "std_ms": round(math.sqrt(max(self.m2, 0.0) / (g.n - 1)), 3) if g.n > 1 else None,
                "min_ms": None if self.lo is None else round(self.lo, 3),
                "max_ms": None if self.hi is None else round(self.hi, 3)}


class Polls:
    """Every request type's poll cycle (see the module doc)."""

    def __init__(self, max_types: int = MAX_TYPES) -> None:
        self.types: dict[tuple, PollType] = {}
        self.max_types = max_types
        self.untracked = 0  # requests of types past max_types

    def new_capture(self) -> None:
        """The next capture's first request of a type starts its period afresh."""
        for p in self.types.values():
            p.last_ns = None

    def request(self, f) -> None:
        key = request_type(f)
        p = self.types.get(key)
        if p is not None:
            p.add(f.t_ns, f.index)
        elif len(self.types) < self.max_types:
            self.types[key] = PollType(key, f.t_ns, type_label(f, key))
        else:
            self.untracked += 1

    def to_dict(self) -> dict:
        ordered = sorted(self.types.values(), key=lambda p: (-p.count, p.label))
        plotted = [p for p in ordered if p.gaps.n > 1][:PLOTTED]
        return {"rows": [p.row() for p in sorted(ordered, key=lambda p: (p.key[0], p.key[1], p.label))],
                "series": [{"label": p.label, **series_points(p.series)} for p in plotted],
                "types": len(self.types), "untracked": self.untracked}
