"""The statistics findings rest on, each in bounded memory: quantiles, rates over time, and three tests.

* `Quantiles` (semdiff's: exact up to 2,000 samples here, then a 0.1 % log histogram);
* `TimeBins`: a value's median per stretch of capture time, at most `MAX_BINS` stretches (they double
  in width as the capture grows), for a trend;
* `two_proportions(a, n, b, m)`: is rate a/n above rate b/m (one-sided z test);
* `rayleigh(n, c, s)`: are n phases (sums of cos and sin) spread evenly round the circle;
* `spearman(xs, ys)`: rank correlation of a trend, with its p.
"""

from __future__ import annotations

import math
from collections import Counter

from sniffer.analysis.diff import Quantiles as _Quantiles

__all__ = ["Quantiles", "TimeBins", "two_proportions", "rayleigh", "spearman", "normal_sf"]

MAX_BINS = 64


class Quantiles(_Quantiles):
    """semdiff's quantiles, exact for fewer samples (a few kB a unit or request type: a line of 247 units
    stays small), then its 0.1 % log histogram."""

    EXACT = 2000
_LOG = math.log1p(0.02)  # 2 % buckets for a bin's median


def normal_sf(z: float) -> float:
    """P(Z > z) of a standard normal."""
    return 0.5 * math.erfc(z / math.sqrt(2))


def two_proportions(a: int, n: int, b: int, m: int) -> tuple[float, float]:
    """(z, one-sided p) that the rate a/n is above b/m."""
    if n == 0 or m == 0:
        return 0.0, 1.0
    p = (a + b) / (n + m)
    se = math.sqrt(p * (1 - p) * (1 / n + 1 / m))
    if se == 0:
        return 0.0, 1.0
    z = (a / n - b / m) / se
    return z, normal_sf(z)


def rayleigh(n: int, c: float, s: float) -> tuple[float, float]:
    """(mean resultant length R, p that the phases are spread evenly): small p = they cluster."""
    if n == 0:
        return 0.0, 1.0
    r = math.hypot(c, s) / n
    z = n * r * r
    p = math.exp(-z) * (1 + (2 * z - z * z) / (4 * n) - (24 * z - 132 * z * z + 76 * z ** 3 - 9 * z ** 4) /
                        (288 * n * n))
    return r, min(1.0, max(0.0, p))


def _ranks(xs: list[float]) -> list[float]:
    order = sorted(range(len(xs)), key=xs.__getitem__)
    ranks = [0.0] * len(xs)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and xs[order[j + 1]] == xs[order[i]]:
            j += 1
        for k in range(i, j + 1):
            ranks[order[k]] = (i + j) / 2
        i = j + 1
    return ranks


def spearman(xs: list[float], ys: list[float]) -> tuple[float, float]:
    """(rho, two-sided p) of a rank correlation (t approximation with n - 2 degrees, as a normal)."""
    n = len(xs)
    if n < 4:
        return 0.0, 1.0
    rx, ry = _ranks(xs), _ranks(ys)
    mx, my = sum(rx) / n, sum(ry) / n
    cov = sum((a - mx) * (b - my) for a, b in zip(rx, ry))
    vx = math.sqrt(sum((a - mx) ** 2 for a in rx))
    vy = math.sqrt(sum((b - my) ** 2 for b in ry))
    if vx == 0 or vy == 0:
        return 0.0, 1.0
    rho = cov / (vx * vy)
    if abs(rho) >= 1:
        return rho, 0.0
    t = rho * math.sqrt((n - 2) / (1 - rho * rho))
    return rho, 2 * normal_sf(abs(t))


class TimeBins:
    """A positive value's median per stretch of capture time (bounded: stretches double as time goes on)."""

    def __init__(self, width_ns: int = 1_000_000_000) -> None:
        self.width = width_ns
        self.t0: int | None = None
        self.bins: dict[int, Counter] = {}

    def add(self, t_ns: int, v: float) -> None:
        if v <= 0:
            return
        if self.t0 is None:
            self.t0 = t_ns
        k = (t_ns - self.t0) // self.width
        while k >= MAX_BINS:
            self._coarser()
            k = (t_ns - self.t0) // self.width
        b = self.bins.get(k)
        if b is None:
            b = self.bins[k] = Counter()
        b[int(math.log(v) / _LOG)] += 1

    def _coarser(self) -> None:
        merged: dict[int, Counter] = {}
        for k, c in self.bins.items():
            merged.setdefault(k // 2, Counter()).update(c)
        self.bins = merged
        self.width *= 2

    def medians(self, min_n: int = 5) -> list[tuple[float, float, int]]:
        """(stretch middle in seconds from the first sample, median, samples) of each stretch with min_n."""
        out = []
        for k in sorted(self.bins):
            c = self.bins[k]
            n = sum(c.values())
            if n < min_n:
                continue
            half, run = n / 2, 0
            for b in sorted(c):
                run += c[b]
                if run >= half:
                    out.append(((k + 0.5) * self.width / 1e9, math.exp((b + 0.5) * _LOG), n))
                    break
        return out
