"""When answers come: timeout_too_short, latency_drift.

* timeout_too_short: the master's timeout shows in its waits (a request left unanswered, then its
  retry or its next request that many ms later: their median is the master's implied timeout); a unit
  that answers after it leaves two traces: answers paired late (pair.late_response: they came after the
  master's next request, or collided with it) and answers to retries that come far later than the unit
  ever answers a first try (they answer the first try: the master took them for the retry's).  The unit's
  answer times measured from the request they answer, against the master's wait, give the timeout to set;
* latency_drift: a unit's answer time (its ordinary answers) per stretch of capture time, ranked against
  time (Spearman), and how far the last third's median moved from the first third's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math

from sniffer.diagnose.codesets import LATE, RETRY, UNANSWERED
from sniffer.codes import WARNING
from sniffer.events import PER_READ
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.episodes import Episode
from sniffer.diagnose.finding import Finding, count_of
from sniffer.diagnose.stats import Quantiles, spearman

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MIN_LATE = 3
TAIL_NEAR = 0.6  # a slowest answer in time this close to the master's wait: a tail that crosses it
MIN_BINS = 8
DRIFT_P = 1e-3
DRIFT_RATIO = 1.5
RISE_RUN = 5  # stretches in a row: a drift that came and went


class _Waits:
    __slots__ = ("gave_up", "late", "true_lat", "frames")

    def __init__(self) -> None:
        self.gave_up = Quantiles()  # ms the master waited before its next request / retry
        self.late: list[tuple[float, int]] = []  # (ms after its request, index) of answers paired late
        self.true_lat = Quantiles()  # ms from the request answered, late ones included
        self.frames: list[int] = []


class TimingGroup(Group):
    def __init__(self) -> None:
        self.waits: dict[tuple, _Waits] = {}
        self.last_req: dict[str, tuple] = {}  # link -> (unit, t_end_ns, unanswered)
        self.retry_of: dict[int, int] = {}  # retry's index -> its first try's end (ns), bounded
        self.last_unanswered: dict[tuple, tuple] = {}  # (link, unit) -> (raw, t_end_ns) of its last unanswered request
        self.retry_answers: list = []  # (link, unit, latency from the retry, from the first try, index)

    def _w(self, link: Link, unit: int) -> _Waits:
        w = self.waits.get((link.name, unit))
        if w is None:
            w = self.waits[(link.name, unit)] = _Waits()
        return w

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if f.unit:
            last = self.last_req.get(link.name)
            if last is not None and last[2]:  # the one before got no answer: the master waited this long ...
                wait = (f.t_ns - last[1]) / 1e6
                u = link.units.get(last[0])
                # ... unless the next request came inside the unit's own answer time: another master's request
                # (or a collision) cut the exchange short, which says nothing of the first master's timeout
                if u is None or u.lat.n < 5 or wait > 2 * u.typical() + 2 * link.char_ns / 1e6:
                    self._w(link, last[0]).gave_up.add(wait)
            unanswered = not UNANSWERED.isdisjoint(codes)
            if not codes:
                self.last_req[link.name] = (f.unit, f.t_end_ns, False)
                return
            uk = (link.name, f.unit)
            if not RETRY.isdisjoint(codes):
                first = self.last_unanswered.get(uk)
                if first is not None and first[0] == f.raw:
                    self.retry_of[f.index] = first[1]
                    if len(self.retry_of) > 1024:
                        self.retry_of.pop(next(iter(self.retry_of)))
            if unanswered and (uk not in self.last_unanswered or RETRY.isdisjoint(codes)):
                self.last_unanswered[uk] = (f.raw, f.t_end_ns)
            self.last_req[link.name] = (f.unit, f.t_end_ns, unanswered)

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if unit is not None and f.crc_ok and f.latency_ms is not None:
            w = self._w(link, unit.unit)
            if not LATE.isdisjoint(codes):
                if len(w.late) < 1024:
                    w.late.append((f.latency_ms, f.index))
                return
            first_end = self.retry_of.pop(f.pair, None) if self.retry_of and f.pair is not None else None
            if first_end is not None:
                if req is not None and len(self.retry_answers) < 4096:
                    self.retry_answers.append((link.name, unit.unit, f.latency_ms,
                                               f.latency_ms + (req[1].t_end_ns - first_end) / 1e6, f.index))
            else:
                w.true_lat.add(f.latency_ms)

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for (name, unit), w in self.waits.items():
            u = d.links[name].units.get(unit)
            if u is None or not u.present:
                continue
            f = self._too_short(d, d.links[name], u, w)
            if f is not None:
                out.append(f)
        for link in d.links.values():
            for u in link.units.values():
                f = self._drift(d, link, u)
                if f is not None:
                    out.append(f)
        return out

    def _too_short(self, d: Diagnosis, link: Link, u: Unit, w: _Waits) -> Finding | None:
        ordinary = u.lat
        if ordinary.n < 5 and not w.late:
            return None
        master = w.gave_up.pct(0.5) if w.gave_up.n >= 3 else None
        # an answer of this unit belongs to a request it answers late only within a few of the master's waits
        # (later ones answer requests the sniffer never saw: a line that loses frames)
        reach = 3 * master if master is not None else float("inf")
        p99 = ordinary.pct(0.99) if ordinary.n else 0.0
        floor = max(2 * p99, p99 + 2 * link.char_ns / 1e6)
        slow = [(a, b, i) for n, x, a, b, i in self.retry_answers
                if n == link.name and x == u.unit and a > floor and b <= reach]
        # an answer paired late that came within the unit's ordinary answer time was cut short by a request
        # sent inside its turnaround (a second master, a collision): not a slow answer
        late = [(ms, i) for ms, i in w.late if floor < ms <= reach]
        hits = len(late) + len(slow)
        tail = ordinary.pct(1.0) if ordinary.n else 0.0
        if (hits < MIN_LATE or hits < 0.01 * max(u.answers, 1)) and master is not None and ordinary.n >= 20 \
                and tail >= TAIL_NEAR * master:
            # a mild one: the unit's slowest answers in time come close to the master's wait, so the answers
            # that came only after the master's retry (counted from the first try, past the wait) are its tail
            # beyond the timeout, not lost requests answered again
            slow = [(a, b, i) for n, x, a, b, i in self.retry_answers
                    if n == link.name and x == u.unit and master < b <= reach]
            late = [(ms, i) for ms, i in w.late if master < ms <= reach]
            hits = len(late) + len(slow)
        if hits < MIN_LATE or hits < 0.01 * max(u.answers, 1):
            return None
        worst = max([w.true_lat.pct(1.0) or 0.0, *(b for _, b, _ in slow), *(ms for ms, _ in late)])
        advice = max(10 * math.ceil(worst * 1.5 / 10), 10 * math.ceil(((master or 0) + 10) / 10))
        ev = {"answers": u.answers, "late_answers": len(late), "answers_after_a_retry": len(slow),
              "share_after_the_timeout": round(hits / max(u.answers, 1), 3),
              "latency_p50_ms": round(ordinary.pct(0.5), 2) if ordinary.n else None,
              "latency_p95_ms": round(ordinary.pct(0.95), 2) if ordinary.n else None,
              "latency_max_ms": round(worst, 2), "recommended_timeout_ms": advice}
        if master is not None:
            ev["master_gives_up_after_ms"] = round(master, 1)
            ev["master_waits_measured"] = w.gave_up.n
        gave = f"the master gives up after about {master:.0f} ms, " if master is not None else ""
        return Finding(
            "timeout_too_short", WARNING, unit=u.unit, link=link.name, t_start=d.seconds(u.first_ns),
            t_end=d.seconds(u.last_ns), evidence=ev, frames=[i for _, i in late[:4]] + [i for _, _, i in slow[:4]],
            statistic={"test": "answers after the master's wait", "value": hits,
                       "share": round(hits / max(u.answers, 1), 3)},
            text=f"Unit {u.unit} answers after the master has given up: {gave}and {hits} of its answers came later "
                 f"(up to {worst:.0f} ms after their request), alone after the master's next request or retry, "
                 f"where the master takes them for the wrong request or they collide.",
            action=f"Set the master's response timeout for unit {u.unit} to about {advice} ms (its slowest answer "
                   f"with a margin), or find out why the unit is that slow (busy with an EEPROM save, a long read).")

    def _drift(self, d: Diagnosis, link: Link, u: Unit) -> Finding | None:
        if not u.present:
            return None
        meds = u.lat_bins.medians()
        if len(meds) < MIN_BINS:
            return None
        xs, ys = [m[0] for m in meds], [m[1] for m in meds]
        rho, p = spearman(xs, ys)
        third = max(len(meds) // 3, 1)
        a = sorted(ys[:third])[third // 2]
        b = sorted(ys[-third:])[third // 2]
        ratio = b / a if a > 0 else 1.0
        per_read = sum(link.time_sources.get(s, 0) for s in PER_READ) > link.time_sources.get("byte", 0)
        least = max(1.0, 2 * link.char_ns / 1e6) * (3 if per_read else 1)  # ms: read times blur a small shift
        if p > DRIFT_P or abs(b - a) < least or not (ratio >= DRIFT_RATIO or ratio <= 1 / DRIFT_RATIO):
            return self._rise(d, link, u, meds, least)
        way = "grows" if b > a else "shrinks"
        return Finding(
            "latency_drift", WARNING, unit=u.unit, link=link.name, t_start=d.seconds(u.first_ns),
            t_end=d.seconds(u.last_ns),
            frames=[u.first_answer, u.last_answer] if u.first_answer is not None else [],
            evidence={"median_first_third_ms": round(a, 2), "median_last_third_ms": round(b, 2),
                      "ratio": round(ratio, 2), "stretches": len(meds), "answers": u.lat.n},
            statistic={"test": "Spearman rank correlation of the answer time with capture time",
                       "rho": round(rho, 3), "p": p},
            text=f"Unit {u.unit}'s answer time {way} through the capture: median {a:.1f} ms in the first third, "
                 f"{b:.1f} ms in the last.",
            action=f"Watch unit {u.unit}: a drive that answers ever slower is busier (a fault log filling, a "
                   f"hot CPU, a scan it runs); at this rate it will outgrow the master's timeout.")

    def _rise(self, d: Diagnosis, link: Link, u: Unit, meds: list, least: float) -> Finding | None:
        """A drift that came and went: a run of at least RISE_RUN stretches (and a tenth of them) whose median
        answer time is DRIFT_RATIO times the unit's usual one (the median of its stretches) and `least` ms above,
        in under half of the capture (else it is the usual).  An episode each such run."""
        ys = sorted(m[1] for m in meds)
        usual = ys[len(ys) // 2]
        runs: list[list] = []
        for mid, med, n in meds:
            if usual > 0 and med >= DRIFT_RATIO * usual and med - usual >= least:
                if runs and abs(mid - runs[-1][3] - u.lat_bins.width / 1e9) < 1e-6:  # the stretch after
                    runs[-1][1:4] = [max(runs[-1][1], med), runs[-1][2] + n, mid]
                    runs[-1][4] += 1
                else:
                    runs.append([mid, med, n, mid, 1])
        need = max(RISE_RUN, len(meds) // 10)
        runs = [r for r in runs if r[4] >= need]
        if not runs or sum(r[4] for r in runs) > len(meds) // 2:
            return None
        half = u.lat_bins.width / 2e9
        base = d.seconds(u.lat_bins.t0) or 0.0
        top = max(r[1] for r in runs)
        episodes = [Episode(base + r[0] - half, base + r[3] + half, r[2], f"answers while the median was "
                            f"{DRIFT_RATIO:g} times the usual {usual:.1f} ms or more") for r in runs]
        first = episodes[0]
        return Finding(
            "latency_drift", WARNING, unit=u.unit, link=link.name, t_start=first.from_s, t_end=episodes[-1].to_s,
            frames=[u.first_answer, u.last_answer] if u.first_answer is not None else [], episodes=episodes,
            evidence={"usual_median_ms": round(usual, 2), "highest_median_ms": round(top, 2),
                      "stretches": len(meds), "stretches_slow": sum(r[4] for r in runs), "answers": u.lat.n},
            text=f"Unit {u.unit}'s answer time rose for a while: from {first.from_s:.0f} s to {first.to_s:.0f} s its "
                 f"median reached {top:.1f} ms, against {usual:.1f} ms the rest of the capture"
                 + (f" ({count_of(len(episodes), 'time')} in all)" if len(episodes) > 1 else "") + ".",
            action=f"Watch unit {u.unit}: a drive that answers slower for a while is busier then (a fault log "
                   f"being written, a scan, a hot CPU); if it comes back, find what it does at those times.")
