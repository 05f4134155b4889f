"""noise_correlated_with_load: the line's damage against what every drive does.

Every frame of a link is damaged or not (a CRC error, a UART flag, noise).  Each drive whose model names
the registers keeps its last decoded process values (its signals): output frequency, output current,
torque where the map has one, the output frequency's rate of change (acceleration: a ramp), the current's
rate of change, and running or stopped.  Every frame is counted against each signal's value at the time, in
steps of the signal's unit (`_STEP`), so memory stays bounded.

At the end each (drive, signal) is tested at a few levels (the signal's deciles over the frames): the
damage rate of the frames while the signal was above the level against below, a one-sided two-proportion
z test.  With drives x signals x levels tests made, the p is multiplied by their number (Bonferroni).  The
best test under LOAD_P with a rate at least twice the other names the drive and the signal (the others
that pass are named as following it: current follows acceleration).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.codes import WARNING
from sniffer.diagnose.codesets import UART
from sniffer.diagnose.finding import Finding
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.stats import two_proportions

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

LOAD_P = 1e-4  # after Bonferroni
MIN_BAD = 10
LEVELS = 9  # levels tested per signal (deciles)
STALE_NS = 5_000_000_000  # a rate of change from readings further apart says nothing about a ramp
# register names (the maps' own, lower case) -> signal
_REGISTERS = {"output frequency": "frequency", "output current": "current", "output torque": "torque",
              "torque": "torque"}
# signal -> (words, unit, step of its bins)
_SIGNALS = {
    "frequency": ("output frequency", "Hz", 1.0),
    "current": ("output current", "A", 0.5),
    "torque": ("torque", "", 5.0),
    "acceleration": ("acceleration (the output frequency's rate of change)", "Hz/s", 1.0),
    "current_rate": ("the output current's rate of change", "A/s", 1.0),
    "running": ("running (against stopped)", "", 1.0),
}


class CorrelateGroup(Group):
    def __init__(self) -> None:
        self.registers: dict[tuple, dict[int, str]] = {}  # (link, unit, model) -> register address -> signal
        self.now: dict[str, dict[tuple, float]] = {}  # link -> (unit, signal) -> its value now (a bin)
        self.last: dict[tuple, tuple] = {}  # (link, unit, signal) -> (t_ns, value): for the rates of change
        self.bins: dict[tuple, dict[int, list]] = {}  # (link, unit, signal) -> bin -> [frames, damaged]
        self.examples: dict[tuple, list[int]] = {}  # (link, unit, signal) -> damaged frames while above its middle
        self.top: dict[tuple, int] = {}
        # link -> [(key, step, [frames, damaged])] of its values now: the bins every frame counts in, found once
        # per read of the drives (a frame between two reads costs no key, no division, no look-up)
        self.cells: dict[str, list] = {}

    # ------------------------------------------------------------ frames
    def noise(self, f, link: Link, codes: frozenset) -> None:
        if self.now:
            self._count(link, True, f.index, link.cut)

    def other(self, f, link: Link, unit: Unit | None, codes: frozenset) -> None:
        if self.now:
            self._count(link, _bad(f, codes), f.index, link.cut)

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if self.now:
            self._count(link, _bad(f, codes), f.index)

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if self.now:
            self._count(link, _bad(f, codes), f.index, link.cut)
        # `points` last: reading it builds a block's dicts, which only a drive's own map can use here
        if (unit is None or not f.crc_ok or f.function not in (0x03, 0x04) or f.model is None
                or f.model == "generic" or not f.points):
            return
        key = (link.name, unit.unit, f.model)
        regs = self.registers.get(key)
        if regs is None:
            regs = self.registers[key] = _registers(link, f.model)
        if regs:
            self._read(f, link, unit.unit, regs)

    def _read(self, f, link: Link, unit: int, regs: dict[int, str]) -> None:
        now = self.now.setdefault(link.name, {})
        self.cells.pop(link.name, None)  # the values change: the bins are found again at the next frame
        for p in f.points:
            sig = regs.get(p.get("address"))
            v = p.get("value")
            if sig is None or not isinstance(v, (int, float)) or isinstance(v, bool):
                continue
            v = float(v)
            now[(unit, sig)] = v
            if sig == "frequency":
                now[(unit, "running")] = 1.0 if v > 0.05 else 0.0
            if sig in ("frequency", "current"):
                k = (link.name, unit, sig)
                was = self.last.get(k)
                self.last[k] = (f.t_ns, v)
                if was is not None and 0 < f.t_ns - was[0] < STALE_NS:
                    rate = "acceleration" if sig == "frequency" else "current_rate"
                    now[(unit, rate)] = (v - was[1]) / ((f.t_ns - was[0]) / 1e9)

    def _count(self, link: Link, bad: bool, index: int, cut: tuple | None = None) -> None:
        now = self.now.get(link.name)
        if not now:
            return
        cells = self.cells.get(link.name)
        if cells is None:
            cells = self.cells[link.name] = self._cells(link.name, now)
        for k, step, x in cells:
            x[0] += 1
            if bad:
                x[1] += 1
                if cut is not None:  # a driver's signature: set apart, in case a driver finding explains it
                    if len(x) == 2:
                        x.append({})
                    x[2][cut] = x[2].get(cut, 0) + 1
                top = self.top[k] = max(self.top.get(k, step), step)
                if step > 0 and step * 2 >= top:
                    ex = self.examples.setdefault(k, [])
                    if len(ex) < 8:
                        ex.append(index)

    def _cells(self, name: str, now: dict) -> list:
        cells = []
        for (unit, sig), v in now.items():
            k = (name, unit, sig)
            b = self.bins.get(k)
            if b is None:
                b = self.bins[k] = {}
            step = int(v // _SIGNALS[sig][2])
            x = b.get(step)
            if x is None:
                x = b[step] = [0, 0]
            cells.append((k, step, x))
        return cells

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        tests = []
        cut = _drivers_named(d)
        for k, bins in self.bins.items():
            if cut:
                bins = _without_cuts(bins, {(u, field) for name, u, field in cut if name == k[0]})
            bad = sum(x[1] for x in bins.values())
            if bad < MIN_BAD or len(bins) < 2:
                continue
            tests += [(k, *t) for t in _splits(bins)]
        if not tests:
            return []
        m = len(tests)
        passed = []
        for (name, unit, sig), level, n_hi, b_hi, n_lo, b_lo in tests:
            z, p = two_proportions(b_hi, n_hi, b_lo, n_lo)
            r_hi, r_lo = b_hi / n_hi, b_lo / n_lo
            if min(1.0, p * m) < LOAD_P and r_hi >= 2 * r_lo + 0.01:
                passed.append((p, name, unit, sig, level, n_hi, b_hi, n_lo, b_lo, z))
        out = []
        for name in sorted({t[1] for t in passed}):
            rows = sorted(t for t in passed if t[1] == name)
            p, _, unit, sig, level, n_hi, b_hi, n_lo, b_lo, z = rows[0]
            link = d.links[name]
            words, eng, step = _SIGNALS[sig]
            short = words.split(" (")[0]
            also = sorted({_SIGNALS[s][0].split(" (")[0] for _, _, u, s, *_ in rows
                           if (u, s) != (unit, sig) and u == unit})
            others = sorted({u for _, _, u, *_ in rows if u != unit})
            lvl = level * step
            where = ("while it runs" if sig == "running" else
                     f"while its {short} is above {lvl:g} {eng}".rstrip())
            follows = f" ({', '.join(also[:3])} follow{'s' * (len(also) == 1)} it too)" if also else ""
            out.append(Finding(
                "noise_correlated_with_load", WARNING, unit=unit, link=name, t_start=d.seconds(link.first_ns),
                t_end=d.seconds(link.last_ns),
                evidence={"drive": unit, "signal": words, "level": round(lvl, 2), "level_unit": eng,
                          "frames_above": n_hi, "damaged_above": b_hi, "frames_below": n_lo, "damaged_below": b_lo,
                          "rate_above": round(b_hi / n_hi, 4), "rate_below": round(b_lo / n_lo, 4),
                          **({"also_following": also} if also else {}),
                          **({"other_drives_following": others} if others else {})},
                statistic={"test": "two-proportion z test, one-sided, Bonferroni", "z": round(z, 2), "p": p,
                           "tests": m, "p_adjusted": min(1.0, p * m)},
                frames=self.examples.get((name, unit, sig), []),
                episodes=link.damage.episodes(d.seconds, "damaged frames"),
                text=f"The line's errors follow unit {unit}'s {short}: {b_hi / n_hi:.1%} of the frames are damaged "
                     f"{where}, {b_lo / n_lo:.1%} otherwise{follows}: interference from its motor side.",
                action=f"Check unit {unit}'s motor cable and screen (360-degree clamp at the drive, away from the "
                       f"RS-485 cable), its EMC filter and earthing"
                       + ("; its ramps draw the most current: a longer acceleration time eases them"
                          if sig in ("acceleration", "current_rate") else "")
                       + "; route the bus cable apart and earth its screen at one end."))
        return out


def _splits(bins: dict[int, list]) -> list[tuple]:
    """(level, frames above, damaged above, frames at or below, damaged at or below) at the signal's deciles."""
    steps = sorted(bins)
    total = sum(bins[s][0] for s in steps)
    bad = sum(bins[s][1] for s in steps)
    levels = []
    run = 0
    for s in steps[:-1]:
        run += bins[s][0]
        q = run / total
        if not levels or q - levels[-1][1] >= 1 / (LEVELS + 1):
            levels.append((s, q))
    out = []
    for s, _ in levels[-LEVELS:] if len(levels) > LEVELS else levels:
        n_lo = sum(bins[x][0] for x in steps if x <= s)
        b_lo = sum(bins[x][1] for x in steps if x <= s)
        out.append((s + 1, total - n_lo, bad - b_lo, n_lo, b_lo))
    return [t for t in out if t[1] and t[3]]


def _drivers_named(d: Diagnosis) -> set:
    from sniffer.diagnose.wiring import WiringGroup

    return set().union(*(g.cut(d) for g in d.groups if isinstance(g, WiringGroup)))


def _without_cuts(bins: dict[int, list], cut: set) -> dict[int, list]:
    """The bins without the answers a driver fault named on the link damaged (its cut first or last bytes):
    a unit whose answers are mostly cut would hide the load's interference under the cut's damage, which has
    nothing to do with the load.  The frames go from both counts: they were no chance for the noise to show."""
    if not cut:
        return bins
    out = {}
    for step, x in bins.items():
        gone = sum(n for c, n in x[2].items() if c in cut) if len(x) > 2 else 0
        out[step] = [x[0] - gone, x[1] - gone]
    return out


def _registers(link: Link, model: str | None) -> dict[int, str]:
    """The registers that carry a signal in the model a frame was decoded with (Link.decoder: not the registry's
    naming now, which by parts may be another part's): address -> signal ({} when none)."""
    try:
        rows = link.decoder(model).map.registers.values()
    except AttributeError:
        return {}
    return {r.addr: _REGISTERS[(r.name or "").strip().lower()] for r in rows
            if (r.name or "").strip().lower() in _REGISTERS}


def _bad(f, codes: frozenset) -> bool:
    return f.crc_ok is False or bool(codes) and not UART.isdisjoint(codes)
