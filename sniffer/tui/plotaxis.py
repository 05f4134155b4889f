"""The plot's axis labels, free of Textual: 1-2-5 steps, tick positions and labels, the time axis's ticks
in the frame list's time base (seconds since the start, from the reference frame, or the wall clock)."""

from __future__ import annotations

import math

from sniffer.tui.timebase import REL, WALL, TimeBase


def nice_step(span: float, count: int) -> float:
    """A 1-2-5 step giving about `count` intervals over `span`."""
    raw = span / max(count, 1)
    if raw <= 0 or not math.isfinite(raw):
        return 1.0
    mag = 10.0 ** math.floor(math.log10(raw))
    return next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw * 0.999)


def ticks(lo: float, hi: float, step: float) -> list[float]:
    first = math.ceil(lo / step - 1e-9) * step
    n = int((hi - first) / step + 1e-9) + 1
    return [first + i * step for i in range(max(n, 0))]


def tick_text(x: float, step: float, width: int = 8) -> str:
    """A tick label: as many decimals as the step needs, exponent form when it would not fit."""
    decimals = max(0, -math.floor(math.log10(step) + 1e-9)) if step > 0 else 0
    s = f"{x:.{decimals}f}"
    if s.startswith("-") and float(s) == 0:
        s = s[1:]
    return s if len(s) <= width else f"{x:.2g}"


WALL_STEPS_S = (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400)


def time_ticks(base: TimeBase, lo: float, hi: float, count: int) -> tuple[list[tuple[float, str]], str]:
    """([(capture time ns, label)], unit after the labels) of about `count` ticks over [lo, hi), in the time
    base the frame list shows: seconds since the start, seconds from the reference frame (signed), or the
    wall clock (ticks on whole seconds, minutes, hours of the viewer's zone)."""
    if base.mode == WALL:  # in integer ns: Unix times in ns are beyond a float's exactness
        lo_ns, hi_ns = int(lo), int(hi)
        raw = (hi - lo) / 1e9 / max(count, 1)
        step = (nice_step((hi - lo) / 1e9, count) if raw < 1 else
                next((s for s in WALL_STEPS_S if s >= raw * 0.999), math.ceil(raw / 86400) * 86400))
        step_ns = max(round(step * 1e9), 1)
        local = base.wall_ns(0) + int(base.wall_datetime(lo_ns).utcoffset().total_seconds()) * 1_000_000_000
        out = []
        t = -(-(lo_ns + local) // step_ns) * step_ns - local  # whole local steps: minutes, hours in the zone
        while t <= hi_ns:
            when = base.wall_datetime(t)
            label = (f"{when:%H:%M:%S}" if step >= 1 else f"{when:%M:%S}.{when.microsecond // 1000:03d}"
                     if step >= 0.001 else f"{when:%S}.{when.microsecond:06d}")
            out.append((t, label))
            t += step_ns
        return out, time_unit(base, lo_ns)
    origin = base.origin_ns()
    step = nice_step((hi - lo) / 1e9, count)
    seconds = ticks((lo - origin) / 1e9, (hi - origin) / 1e9, step)
    return [(origin + s * 1e9, tick_text(s, step, 12)) for s in seconds], time_unit(base, int(lo))


def time_unit(base: TimeBase, t_ns: int) -> str:
    """What a time of the base is counted in: seconds, seconds from the reference, the wall clock's zone."""
    if base.mode == WALL:
        return base.wall_datetime(t_ns).tzname() or ""
    return "s" if base.mode == REL else f"s from #{base.ref_index}"
