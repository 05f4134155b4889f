"""The units a line's master polls, and how often: from the fitting requests of one listen.

A PLC polls in cycles: the same request (function, address, count) comes back
once a cycle, or every few cycles.  A unit's poll period is the shortest median
interval between repeats of one of its requests; its request rate counts them all.
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import median

from sniffer.frame import Frame


@dataclass(frozen=True)
class UnitSeen:
    unit: int
    requests: int
    period_s: float | None  # the same request again after this long (None: none repeated)
    functions: tuple[int, ...]

    def describe(self, seconds: float) -> str:
        every = f"polled every {self.period_s * 1e3:.0f} ms" if self.period_s else "no request repeated yet"
        fcs = " ".join(f"{f:02X}H" for f in self.functions)
        code = "function code" + ("s" if len(self.functions) > 1 else "")
        return f"unit {self.unit}: {every}, {self.requests} requests in {seconds:.1f} s, {code} {fcs}"


class UnitPolls:
    def __init__(self) -> None:
        self._last: dict[tuple, int] = {}  # (unit, function, address and count) -> last time
        self._gaps: dict[tuple, list[int]] = {}
        self._count: dict[int, int] = {}
        self._functions: dict[int, set[int]] = {}

    def add(self, f: Frame) -> None:
        """A fitting request."""
        key = (f.unit, f.adu[1:6])
        if key in self._last:
            gaps = self._gaps.setdefault(key, [])
            if len(gaps) < 64:
                gaps.append(f.t_ns - self._last[key])
        self._last[key] = f.t_ns
        self._count[f.unit] = self._count.get(f.unit, 0) + 1
        self._functions.setdefault(f.unit, set()).add(f.function & 0x7F)

    def seen(self) -> list[UnitSeen]:
        out = []
        for unit in sorted(self._count):
            periods = [median(g) for (u, _), g in self._gaps.items() if u == unit and g]
            out.append(UnitSeen(unit, self._count[unit], min(periods) / 1e9 if periods else None,
                                tuple(sorted(self._functions[unit]))))
        return out
