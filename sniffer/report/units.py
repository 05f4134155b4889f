"""Per unit, as the frames pass: its figures, response latency (histogram, over time) and turnaround.

The counts and the latency quantiles are the unit's `sniffer.analysis.unitfigures.UnitFigures` (one definition
for every view); what only the report draws is kept here beside them.

Turnaround is the silence between a request's last byte and its response's first,
in character times of the capture's line (a response's `latency_ms` over the
character time).  Modbus RTU wants at least t3.5 between frames, and under t1.5 the
two frames are one as far as a strict receiver is concerned: 3.5 and 1.5 characters
up to 19200 baud, 1.75 ms and 750 us above (the serial line spec 2.5.1.1; the line's
`LineSettings.t35_ns` / `t15_ns`, as the framer's `modbus.timing.t35` uses).  How much to
trust it depends on how the timestamps were taken (`Frame.time_source`): per byte
(a logic analyzer, the simulator) it is measured; per USB read it is estimated
from the read times and the baud rate.

Memory per unit is bounded: log-spaced latency bins, `unitfigures.Latencies` for the
quantiles, and the latency over time as an `analysis.history.Series` (thinned into time
buckets, keeping each bucket's first, minimum, maximum and last: the spikes stay).
"""

from __future__ import annotations

import math

from sniffer.analysis.history import Series
from sniffer.analysis.unitfigures import UnitFigures

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
    """One unit's figures (`fig`) and what the report draws of it besides (see the module doc)."""

    __slots__ = ("fig", "unit", "model", "lat_bins", "lat_series", "turn_bins", "below15", "below35", "writes")

    def __init__(self, unit: str, fig: UnitFigures) -> None:
        self.fig = fig
        self.unit = unit  # "3", or "LINK:3" with several links
        self.model: str | None = None  # what the registry settled on ("a510 (given)"); else the frames' model
        self.below15 = self.below35 = self.writes = 0
        self.lat_bins = [0] * LAT_BINS
        self.lat_series = Series(LATENCY_POINTS)
        self.turn_bins = [0] * (TURN_BINS + 1)

    def latency(self, t_ns: int, ms: float, char_ns: int, index: int, t15: float = 1.5, t35: float = 3.5) -> int:
        """A response `ms` after its request ended (turnaround in characters of `char_ns`): 1 if that is under
        t3.5, 2 under t1.5 (both in characters), else 0."""
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
        """The units table's row: the unit's figures (unitfigures.UnitFigures.to_dict), then the report's own."""
        fig = self.fig
        d = fig.to_dict()
        d["unit"] = self.unit
        d["model"] = self.model or fig.model
        first = fig.first_ns if fig.first_ns is not None else origin_ns
        rate = fig.polls_per_s
        d.update(writes=self.writes, polls_per_s=None if rate is None else round(rate, 2),
                 first_s=_r((first - origin_ns) / 1e9), last_s=_r((fig.last_ns - origin_ns) / 1e9),
                 below15=self.below15, below35=self.below35)
        return d


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
