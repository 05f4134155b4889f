"""Who talks as master, and how often it repeats itself: second_master, retry_storm.

* second_master: a master polls in a cycle, so each of its request types (unit, function, address)
  keeps its place in the cycle; a second master's requests come on a schedule of their own and drift
  through the first one's cycle.  Per window of requests (`WINDOW`), each frequent type's phase in the
  cycles of the four most frequent types (`_phases`: the time since an anchor type's last request over that
  cycle's length, and its rank among the cycle's requests: timeouts stretch a cycle's time, not its
  order) falls in twelfths of the cycle.  The types whose phases sit mostly in two twelfths (a request
  polled twice a cycle holds two places) or close around one place (their mean resultant length R)
  against some anchor are one schedule; the ones that do neither against any are another (a second
  master that waits for a quiet line sends more in the first one's idle stretches: its phases are
  spread, not necessarily even).  Two schedules and a sign that they meet (a request sent before the
  unit asked could answer the one before it, whose answer then comes late; bursts of two transmitters
  at once) make the finding; the unit is the one the smaller schedule polls;
* retry_storm: retries (the same request again after no answer) are a large share of the master's
  requests to units that do answer (a silent unit's retries are unit_silent's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math
from collections import Counter

from sniffer.diagnose.codesets import LATE, RETRY, UNANSWERED
from sniffer.codes import ERROR, WARNING
from sniffer.analysis.diff import key_text
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding
from sniffer.diagnose.stats import rayleigh

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

WINDOW = 4000  # requests per phase test
MIN_TYPE = 30  # requests of a type in a window to test it
BINS = 12  # the cycle in twelfths
ANCHORS = 4  # the most frequent types whose cycles the others' phases are taken in
SAMPLE = 4  # after the first SAMPLE windows, one window in SAMPLE is tested (a long capture: the cost stays small)
HELD_SHARE = 0.7  # a type whose phases fall mostly in two twelfths of the cycle (either way) holds its place
SPREAD_SHARE = 0.45  # one whose two busiest twelfths hold less than this (both ways) keeps none ...
HELD_R = 0.6  # ... a mean resultant length of its phases (one place, across the cycle's wrap) of this holds one
SPREAD_R = 0.35  # ... below this (both ways), none
LOOSE_SHARE = 0.5  # one under this and under HELD_R is loose: a second master's if it cuts requests short ...
LOOSE_CUT = 0.2  # ... with requests cut short as many as this share of its requests
RETRY_SHARE = 0.1


class _Link:
    def __init__(self) -> None:
        self.window: list[tuple[int, tuple]] = []  # (t_ns, (unit, fc, addr)) of CRC-good first tries
        self.spread: dict[tuple, list] = {}  # type -> [windows found spread, n, R, p, frames]
        self.held: set[tuple] = set()
        self.loose: dict[tuple, list] = {}  # types neither held nor spread: [windows, n, R, p, share]
        self.gaps: list[tuple[int, float]] = []  # (unit, ms) a request waited unanswered before the next came
        self.last: tuple | None = None  # (unit, t_end_ns, unanswered, index)
        self.bursts = 0
        self.burst_frames: list[int] = []
        self.late = 0
        self.late_frames: list[int] = []
        self.requests = 0
        self.retries: Counter = Counter()
        self.first_ns: int | None = None
        self.last_ns = 0
        self.indices: dict[tuple, list[int]] = {}
        self.times: dict[tuple, list[int]] = {}  # type -> [first t_ns, last t_ns, first tries]
        self.windows = 0


def _top2(hist: Counter, n: int) -> float:
    """The share of a type's phases in its two busiest twelfths of the cycle (two: a type polled twice a
    cycle holds two places)."""
    return sum(v for _, v in hist.most_common(2)) / n


def _phases(win: list, anchor: tuple, counts: Counter) -> dict[tuple, tuple]:
    """type -> (n, share in its two busiest twelfths, R) of the frequent types' phases in the cycle of `anchor`,
    by time (the time since the anchor over the cycle's length) and by rank (requests since the anchor over
    the cycle's requests: a cycle stretched by timeouts and retries shifts a type's time, not its place in
    the order); the better of the two.  R from the twelfths' centres."""
    return _phases_in(_Window(win, counts), anchor)


class _Window:
    """A window of requests as _phases reads it once per anchor: each type as a small number (a type is a
    tuple, hashed again at every look-up; the window is read ANCHORS times) and whether it is frequent."""

    __slots__ = ("times", "ids", "types", "frequent", "id_of")

    def __init__(self, win: list, counts: Counter) -> None:
        self.id_of: dict[tuple, int] = {}
        self.types: list[tuple] = []
        self.times = [t for t, _ in win]
        self.ids = ids = []
        id_of, types = self.id_of, self.types
        for _, k in win:
            i = id_of.get(k)
            if i is None:
                i = id_of[k] = len(types)
                types.append(k)
            ids.append(i)
        self.frequent = [counts[k] >= MIN_TYPE for k in types]


def _phases_in(w: _Window, anchor: tuple) -> dict[tuple, tuple]:
    bins: dict[int, list] = {}
    times, ids, frequent = w.times, w.ids, w.frequent
    a_id = w.id_of.get(anchor)
    at = [i for i, k in enumerate(ids) if k == a_id]
    top = BINS - 1
    for a, b in zip(at, at[1:]):  # one cycle of the anchor
        t_a = times[a]
        span = max(times[b] - t_a, 1)
        size = b - a
        for i in range(a + 1, b):
            k = ids[i]
            if not frequent[k]:
                continue
            x = bins.get(k)
            if x is None:
                x = bins[k] = [0] * (2 * BINS)
            # per-read times are estimated back from the read: a frame may carry a time before the anchor's
            m = (times[i] - t_a) * BINS // span
            x[0 if m < 0 else m if m < top else top] += 1
            # a rank in a cycle of a few requests says nothing (any type keeps one of a few places)
            if size > BINS:
                x[BINS + (i - a) * BINS // size] += 1
    out = {}
    for k, x in bins.items():
        n = sum(x[:BINS])
        if n < MIN_TYPE:
            continue
        best = (0.0, 0.0)
        # ranks only where every cycle was long enough to give one
        for h in (x[:BINS], x[BINS:]) if sum(x[BINS:]) == n else (x[:BINS],):
            top2 = sum(sorted(h)[-2:]) / n
            c = sum(v * _COS[m] for m, v in enumerate(h))
            si = sum(v * _SIN[m] for m, v in enumerate(h))
            best = (max(best[0], top2), max(best[1], math.hypot(c, si) / n))
        out[w.types[k]] = (n, best[0], best[1])
    return out


_COS = [math.cos(2 * math.pi * (m + 0.5) / BINS) for m in range(BINS)]
_SIN = [math.sin(2 * math.pi * (m + 0.5) / BINS) for m in range(BINS)]


class MastersGroup(Group):
    def __init__(self) -> None:
        self.links: dict[str, _Link] = {}

    def _l(self, link: Link) -> _Link:
        x = self.links.get(link.name)
        if x is None:
            x = self.links[link.name] = _Link()
        return x

    def noise(self, f, link: Link, codes: frozenset) -> None:
        if len(f.raw) >= 4:
            self._burst(self._l(link), f)

    def _burst(self, s: _Link, f) -> None:
        s.bursts += 1
        if len(s.burst_frames) < 8:
            s.burst_frames.append(f.index)

    def other(self, f, link: Link, unit: Unit | None, codes: frozenset) -> None:
        if f.crc_ok is False and "modbus.length.mismatch" in codes:
            self._burst(self._l(link), f)

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if not codes:
            return
        s = self._l(link)
        if f.crc_ok is False and "modbus.length.mismatch" in codes:
            self._burst(s, f)
        if not LATE.isdisjoint(codes):
            s.late += 1
            if len(s.late_frames) < 8:
                s.late_frames.append(f.index)

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if not f.unit:
            return
        s = self.links.get(link.name) or self._l(link)
        if s.first_ns is None:
            s.first_ns = f.t_ns
        s.last_ns = f.t_end_ns
        s.requests += 1
        if s.last is not None and s.last[2] and len(s.gaps) < 4096:
            s.gaps.append((s.last[0], (f.t_ns - s.last[1]) / 1e6))
        s.last = (f.unit, f.t_end_ns, not UNANSWERED.isdisjoint(codes), f.index)
        if codes and not RETRY.isdisjoint(codes):
            s.retries[f.unit] += 1
            return
        k = key
        s.window.append((f.t_ns, k))
        tt = s.times.get(k)
        if tt is None:
            s.times[k] = [f.t_ns, f.t_ns, 1]
        else:
            tt[1] = f.t_ns
            tt[2] += 1
        idx = s.indices.get(k)
        if idx is None:  # (not setdefault: that builds a list at every request)
            s.indices[k] = [f.index]
        elif len(idx) < 4:
            idx.append(f.index)
        if len(s.window) >= WINDOW:
            s.windows += 1
            if s.windows <= SAMPLE or s.windows % SAMPLE == 0:
                self._test(s)
            else:
                s.window = []

    def _test(self, s: _Link) -> None:
        """Each frequent type's phases in the cycles of the window's other frequent types (ANCHORS of them):
        a type of the master's cycle keeps a place against some of them; a second master's against none."""
        win, s.window = s.window, []
        counts = Counter(k for _, k in win)
        frequent = [k for k, n in counts.most_common(ANCHORS) if n >= MIN_TYPE]
        if len(frequent) < 2:
            return
        # the master's cycle is the anchor that holds the other types closest to their places (a second
        # master's type, if frequent, holds none of the first master's): every type is judged against that one
        w = _Window(win, counts)
        by_anchor = [(anchor, _phases_in(w, anchor)) for anchor in frequent]
        ref, best = max(by_anchor, key=lambda ab: sum(max(sh, r) for _, sh, r in ab[1].values()) / max(len(ab[1]), 1))
        s.held.add(ref)
        for k, (n, share, r) in best.items():
            if share >= HELD_SHARE or r >= HELD_R:
                s.held.add(k)
            elif share < SPREAD_SHARE and r < SPREAD_R:
                e = s.spread.setdefault(k, [0, 0, 0.0, 0.0, 0.0])
                e[0] += 1
                e[1], e[2], e[3], e[4] = n, r, rayleigh(n, r * n, 0.0)[1], share
            elif share < LOOSE_SHARE and r < HELD_R:
                # loose: what survives of a second master that collides is what it sent into the gaps, which
                # sit at a few places in the cycle; judged with the collisions (`_second`)
                e = s.loose.setdefault(k, [0, 0, 0.0, 0.0, 0.0])
                e[0] += 1
                e[1], e[2], e[3], e[4] = n, r, rayleigh(n, r * n, 0.0)[1], share

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for name, s in self.links.items():
            if len(s.window) >= 4 * MIN_TYPE:
                self._test(s)
            f = self._second(d, d.links[name], s)
            if f is not None:
                out.append(f)
            f = self._retries(d, d.links[name], s)
            if f is not None:
                out.append(f)
        return out

    def _second(self, d: Diagnosis, link: Link, s: _Link) -> Finding | None:
        interrupts = 0
        for unit, gap in s.gaps:
            u = link.units.get(unit)
            med = u.typical() if u is not None and u.lat.n >= 5 else None
            if med is not None and gap < 0.5 * med:
                interrupts += 1
        spread = {k: e for k, e in s.spread.items() if k not in s.held}
        # a loose type is a second master's when requests keep being sent before the unit could answer (a noisy
        # line's damaged bursts do not count: they come with one master too)
        if interrupts >= 10:
            spread.update({k: e for k, e in s.loose.items()
                           if k not in s.held and k not in spread and interrupts >= LOOSE_CUT * e[1]})
        if not spread or not s.held:
            return None
        k0, e0 = max(spread.items(), key=lambda kv: kv[1][1])
        meets = interrupts + s.bursts + s.late
        # one that never meets the first master (it waits for a quiet line) shows by its schedule alone
        if meets < 2 and e0[1] < 2 * MIN_TYPE:
            return None
        units = sorted({k[0] for k in spread})
        unit = units[0] if len(units) == 1 else None
        types = [f"u{k[0]} {key_text(k[1:])}" for k in sorted(spread, key=str)][:6]
        sent = sum(s.times[k][2] for k in spread if k in s.times)
        periods = sorted((s.times[k][1] - s.times[k][0]) / 1e6 / (s.times[k][2] - 1)
                         for k in spread if k in s.times and s.times[k][2] > 1)
        period = periods[len(periods) // 2] if periods else 0.0
        collided = s.bursts  # CRC-damaged bursts: two transmitters at once
        ev = {"its_requests": sent, "its_period_ms": round(period, 1), "it_reads": "; ".join(types),
              "request_types_in_the_first_masters_cycle": len(s.held),
              "collisions_crc_damaged_frames": collided,
              "first_master_requests_cut_short": interrupts, "late_answers": s.late,
              "requests_by_master": _by_master(s, spread)}
        who = f"unit {unit}" if unit is not None else f"units {', '.join(map(str, units))}"
        frames = [i for k in spread for i in s.indices.get(k, [])[:2]] + s.late_frames[:2] + s.burst_frames[:2]
        meet = (f"It collides with the first master: {collided} CRC-damaged frames are two transmitters at once, "
                f"{interrupts} of the first master's requests were cut short before their answer"
                f"{f', {s.late} answers came late' if s.late else ''}." if meets >= 2 else
                "It never talks over the first master (it waits for a quiet line), but its requests fit no slot "
                "of the first master's cycle.")
        return Finding(
            "second_master", ERROR if meets >= 2 else WARNING, unit=unit, link=link.name,
            t_start=d.seconds(s.first_ns), t_end=d.seconds(s.last_ns), evidence=ev, frames=frames,
            statistic={"test": "phase in the poll cycle: share in the two busiest twelfths (a request of the "
                               "cycle: 0.7 or more), and its mean resultant length R", "type": types[0],
                       "n": e0[1], "share": round(e0[4], 3), "R": round(e0[2], 3)},
            text=f"Another master polls {who} on a clock of its own, about every {period:.0f} ms: it reads "
                 f"{', '.join(types[:3])} ({sent} requests), drifting through the poll cycle while {len(s.held)} "
                 f"request types of the first master hold their place. {meet}",
            action="Find the second master (an HMI, a gateway, a laptop left connected) and take it off this line, "
                   "or make it a slave of the PLC: Modbus RTU has one master per line, and answers go to "
                   "whichever request came last.")

    def _retries(self, d: Diagnosis, link: Link, s: _Link) -> Finding | None:
        answering = {u: n for u, n in s.retries.items() if link.units.get(u) is not None and link.units[u].answered}
        total = sum(answering.values())
        if total < 20 or total < RETRY_SHARE * s.requests:
            return None
        top = sorted(answering.items(), key=lambda kv: -kv[1])
        return Finding(
            "retry_storm", WARNING, link=link.name, t_start=d.seconds(s.first_ns), t_end=d.seconds(s.last_ns),
            evidence={"requests": s.requests, "retries": total, "share": round(total / s.requests, 3),
                      "by_unit": {str(u): n for u, n in top[:8]}},
            text=f"{total / s.requests:.0%} of the master's requests are retries ({total} of {s.requests}), mostly to "
                 + ", ".join(f"unit {u} ({n})" for u, n in top[:3]) + ": the line spends that time twice.",
            action="Find why those units miss answers (see the other findings on them); a retry that follows a "
                   "damaged answer is the line's noise, one that follows silence a timeout or a busy drive.")


def _by_master(s: _Link, second: dict) -> dict:
    """Each request type (its first tries) labelled with the master it most likely comes from: the second's
    schedule (drifting through the cycle), the first's (holding a place in it), or neither told ('unsure':
    too rare to test, or between the two).  Most requests first; a type names its unit, function and range."""
    rows = []
    for k, (_, _, n) in s.times.items():
        who = "second" if k in second else "first" if k in s.held else "unsure"
        rows.append((who != "second", -n, f"u{k[0]} {key_text(k[1:])}", who, n))
    rows.sort()
    return {text: {"master": who, "requests": n} for _, _, text, who, n in rows}
