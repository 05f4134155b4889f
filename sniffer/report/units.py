"""Per unit, as the frames pass: counts, response latency (histogram, percentiles, over time) and turnaround.

Turnaround is the silence between a request's last byte and its response's first,
in character times of the capture's line (a response's `latency_ms` over the
character time).  Modbus RTU wants at least t3.5 between frames, and under t1.5 the
two frames are one as far as a strict receiver is concerned: 3.5 and 1.5 characters
up to 19200 baud, 1.75 ms and 750 us above (the serial line spec 2.5.1.1; the line's
`LineSettings.t35_ns` / `t15_ns`, as the framer's `modbus.timing.t35` uses).  How much to
trust it depends on how the timestamps were taken (`Frame.time_source`): per byte
(a logic analyzer, the simulator) it is measured; per USB read it is estimated
from the read times and the baud rate.

Memory per unit is bounded: log-spaced latency bins, `semdiff.Quantiles` for the
percentiles (exact up to 10,000 responses, 0.1 % beyond), and the latency over time
as a `tui.history.Series` (thinned into time buckets, keeping each bucket's first,
minimum, maximum and last: the spikes stay).
"""

from __future__ import annotations

import math

from ..semdiff import Quantiles
from ..tui.history import Series

LAT_BINS_PER_DECADE = 10
LAT_LO_MS = 0.01  # first bin edge; faster answers count in the first bin
LAT_BINS = 70  # 0.01 ms .. 100 s
TURN_STEP = 0.25  # characters per turnaround bin
TURN_BINS = 160  # 0 .. 40 characters; longer ones count in one bin past the last
LATENCY_POINTS = 2048  # kept per unit for the latency over time


def latency_edges() -> list[float]:
    return [round(LAT_LO_MS * 10 ** (i / LAT_BINS_PER_DECADE), 6) for i in range(LAT_BINS + 1)]


def turnaround_edges() -> list[float]:
    return [i * TURN_STEP for i in range(TURN_BINS + 1)]


class UnitAgg:
    """One unit's figures (see the module doc)."""

    __slots__ = ("unit", "model", "requests", "responses", "crc", "exceptions", "timeouts", "retries", "faults",
                 "alarms", "good", "first_ns", "last_ns", "lat", "lat_min", "lat_max", "lat_bins", "lat_series",
                 "unmeasured", "turn_bins", "below15", "below35", "writes")

    def __init__(self, unit: str) -> None:
        self.unit = unit  # "3", or "LINK:3" with several links
        self.model: str | None = None
        self.requests = self.responses = self.crc = self.exceptions = self.timeouts = self.retries = 0
        self.faults = self.alarms = self.good = self.unmeasured = self.below15 = self.below35 = self.writes = 0
        self.first_ns: int | None = None
        self.last_ns = 0
        self.lat = Quantiles()
        self.lat_min: float | None = None
        self.lat_max: float | None = None
        self.lat_bins = [0] * LAT_BINS
        self.lat_series = Series(LATENCY_POINTS)
        self.turn_bins = [0] * (TURN_BINS + 1)

    def latency(self, t_ns: int, ms: float, char_ns: int, index: int, t15: float = 1.5, t35: float = 3.5) -> int:
        """A response `ms` after its request ended (turnaround in characters of `char_ns`): 1 if that is under
        t3.5, 2 under t1.5 (both in characters), else 0."""
        self.lat.add(ms)
        if self.lat_min is None or ms < self.lat_min:
            self.lat_min = ms
        if self.lat_max is None or ms > self.lat_max:
            self.lat_max = ms
        b = int(math.floor(math.log10(ms / LAT_LO_MS) * LAT_BINS_PER_DECADE)) if ms > LAT_LO_MS else 0
        self.lat_bins[min(b, LAT_BINS - 1)] += 1
        self.lat_series.add(t_ns, ms, index)
        if char_ns > 0:
            chars = ms * 1e6 / char_ns
            self.turn_bins[max(0, min(int(chars / TURN_STEP), TURN_BINS))] += 1
            if chars < t35:
                self.below35 += 1
                if chars < t15:
                    self.below15 += 1
                    return 2
                return 1
        return 0

    def row(self, origin_ns: int = 0) -> dict:
        span = ((self.last_ns - self.first_ns) / 1e9) if self.first_ns is not None else 0.0
        return {
            "unit": self.unit, "model": self.model, "ghost": not self.good,
            "requests": self.requests, "responses": self.responses, "crc": self.crc,
            "exceptions": self.exceptions, "timeouts": self.timeouts, "retries": self.retries,
            "faults": self.faults, "alarms": self.alarms, "writes": self.writes, "unmeasured": self.unmeasured,
            "lat_n": self.lat.n, "lat_min": _r(self.lat_min), "lat_median": _r(self.lat.median()),
            "lat_p95": self.lat.pct(0.95), "lat_p99": self.lat.pct(0.99), "lat_max": _r(self.lat_max),
            "polls_per_s": round((self.requests - 1) / span, 2) if span > 0 and self.requests > 1 else None,
            "first_s": _r(((self.first_ns or 0) - origin_ns) / 1e9), "last_s": _r((self.last_ns - origin_ns) / 1e9),
            "below15": self.below15, "below35": self.below35,
        }


def _r(v: float | None, nd: int = 3) -> float | None:
    return None if v is None else round(v, nd)


def series_points(s: Series, hold: bool = False) -> dict:
    """A Series as {"t": seconds, "v": values}: its kept samples (`hold`: and its last value where it ends)."""
    t = [round(x / 1e9, 6) for x in s.t]
    v = [x if math.isfinite(x) else None for x in s.v]  # a float register may hold NaN or infinity: no point
    end_t, _ = s.end
    if hold and s.t and end_t > s.t[-1]:  # the value held on to the end
        t.append(end_t / 1e9)
        v.append(v[-1])
    return {"t": t, "v": v}
