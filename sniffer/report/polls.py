"""Poll cycles: per request type (unit, function, first register, count: `semdiff.request_key`), the time
from one request of that type to the next, i.e. the period the master polls it at, and how much it wanders.

Per type a count, the gap's percentiles (`semdiff.Quantiles`: bounded), its mean and standard deviation
(Welford), and the gaps over time (`tui.history.Series`, thinned).  Jitter is shown as p95 - p5 of the
gaps (a retry or a skipped cycle is an outlier it does not hide behind) and as the standard deviation.
At most MAX_TYPES types are followed; requests of types beyond are counted, not timed.
"""

from __future__ import annotations

import math

from ..protocols import of_frame
from ..semdiff import Quantiles, key_text, request_key
from ..tui.history import Series
from .units import series_points

MAX_TYPES = 512
GAP_POINTS = 1024  # kept per type for the plot
PLOTTED = 12  # the most frequent types get a line in the plot


def request_type(unit: int, f) -> tuple[tuple, str | None]:
    """(key, label or None) of a request: a Modbus request by function, first register and count; another
    protocol's (PD-series: ADDR FUNC LEN DATA) by function and its first data byte (the parameter or status
    selector), labelled with the first such request's summary."""
    proto = of_frame(f.protocol)
    if proto is None or proto.family == "modbus":
        return (unit, *request_key(f)), None
    adu = f.adu
    sel = adu[3] if len(adu) > 3 else None
    return (unit, f.function, "sel", sel), f"u{unit} fc{f.function:02X} {f.summary.split(' = ')[0][:60]}"


class PollType:
    __slots__ = ("key", "count", "last_ns", "gaps", "mean", "m2", "lo", "hi", "series", "name")

    def __init__(self, key: tuple, t_ns: int, name: str | None = None) -> None:
        self.key = key
        self.name = name
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

    @property
    def label(self) -> str:
        if self.name is not None:
            return self.name
        unit, *k = self.key
        return f"u{unit} {key_text(tuple(k))}"

    def row(self) -> dict:
        g = self.gaps
        p5, p50, p95 = g.pct(0.05), g.median(), g.pct(0.95)
        return {"type": self.label, "unit": self.key[0], "count": self.count,
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

    def request(self, unit: int, f) -> None:
        key, name = request_type(unit, f)
        p = self.types.get(key)
        if p is not None:
            p.add(f.t_ns, f.index)
        elif len(self.types) < self.max_types:
            self.types[key] = PollType(key, f.t_ns, name)
        else:
            self.untracked += 1

    def to_dict(self) -> dict:
        ordered = sorted(self.types.values(), key=lambda p: (-p.count, p.label))
        plotted = [p for p in ordered if p.gaps.n > 1][:PLOTTED]
        return {"rows": [p.row() for p in sorted(ordered, key=lambda p: (p.key[0], p.label))],
                "series": [{"label": p.label, **series_points(p.series)} for p in plotted],
                "types": len(self.types), "untracked": self.untracked}
