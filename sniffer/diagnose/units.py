"""Units that do not do what they are asked: unit_silent, unit_refuses, answers_broadcast.

* unit_silent: CRC-good requests to a unit (their address byte is checked, so the unit is the one the
  master meant), and over the whole span no answer from it, good or damaged;
* unit_refuses: the master keeps sending a unit one request it answers with an exception every time
  (an address it does not have, a write it does not allow in this mode); requests refused now and then
  (busy) are no finding;
* answers_broadcast: CRC-good answers from a unit right after a broadcast (unit 0), which no unit may
  answer: they collide with whatever the master sends next.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from collections import Counter

from sniffer.diagnose.codesets import RETRY
from sniffer.codes import ERROR, WARNING
from sniffer.analysis.diff import key_text
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MIN_REQUESTS = 3
MIN_SPAN_NS = 1_000_000_000
REFUSED_SHARE = 0.5  # of one request's tries answered with an exception
MAX_KEYS = 4096


class UnitsGroup(Group):
    def __init__(self) -> None:
        self.plain_by: Counter = Counter()  # (link, unit) -> CRC-good answers naming it to no request known, not echoes
        self.keys: dict[tuple, list] = {}  # (link, unit, key) -> [requests, refusals Counter, frames]
        self.broadcast: dict[tuple, list] = {}  # (link, unit) -> [count, frames]

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if not f.crc_ok or f.unit is None or (req is not None and not codes and not f.exception):
            return  # (a paired answer counts in its Unit already)
        if req is None and f.function not in (0x05, 0x06, 0x08):
            self.plain_by[(link.name, f.unit)] += 1
        if codes and "pair.broadcast_response" in codes:
            b = self.broadcast.setdefault((link.name, f.unit), [0, []])
            b[0] += 1
            if len(b[1]) < 8:
                b[1].append(f.index)
        if f.exception and req is not None:
            e = self._key(link, req[2])
            if e is not None:
                e[1][f.exception.get("code")] += 1
                if len(e[2]) < 8:
                    e[2].append(f.index)

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if f.unit and not (codes and not RETRY.isdisjoint(codes)):
            e = self._key(link, key)
            if e is not None:
                e[0] += 1

    def _key(self, link: Link, key: tuple) -> list | None:
        k = (link.name, key)
        e = self.keys.get(k)
        if e is None:
            if len(self.keys) >= MAX_KEYS:
                return None
            e = self.keys[k] = [0, Counter(), []]
        return e

    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for link in d.links.values():
            for u in link.units.values():
                if u.unit == 0:
                    continue
                f = self._silent(d, link, u)
                if f is not None:
                    out.append(f)
        out += self._refused(d)
        for (name, unit), (n, frames) in self.broadcast.items():
            if n < 2:
                continue
            out.append(Finding(
                "answers_broadcast", WARNING, unit=unit, link=name, evidence={"answers_to_broadcasts": n},
                frames=frames,
                text=f"Unit {unit} answered {n} broadcasts (unit 0), which no unit may answer: its answer can "
                     f"collide with the master's next request.",
                action=f"Check unit {unit}'s address setting (not 0) and its firmware; a broadcast write needs no "
                       f"answer, so the master should not wait for one either."))
        return out

    def _silent(self, d: Diagnosis, link: Link, u: Unit) -> Finding | None:
        if u.requests < MIN_REQUESTS or u.answered:
            return None
        damaged = u.garbled + u.damaged_answers
        if damaged >= MIN_REQUESTS and damaged >= 0.1 * u.requests:
            return None  # damaged answers (or bursts where its answers were due), time and again: it answers
        if u.plain_requests and self.plain_by.get((link.name, u.unit)):
            return None  # it answered (an orphan: its request is no longer remembered)
        if u.first_ns is None or u.last_ns - u.first_ns < MIN_SPAN_NS:
            return None
        span = (u.last_ns - u.first_ns) / 1e9
        echoes = (f" Its {u.echoes} echo-shaped 'answers' repeat their requests byte for byte: the master's "
                  f"retries, not answers.") if u.echoes else ""
        return Finding(
            "unit_silent", ERROR, unit=u.unit, link=link.name, t_start=d.seconds(u.first_ns),
            t_end=d.seconds(u.last_ns), frames=u.frames,
            evidence={"requests": u.requests, "retries": u.retries, "answers": 0, "span_s": round(span, 1)},
            text=f"Unit {u.unit} never answered: {u.requests} requests to it ({u.retries} of them retries) over "
                 f"{span:.1f} s got no response, good or damaged.{echoes}",
            action=f"Check that a drive is set to address {u.unit}, is powered and wired to this line (A/B), and "
                   f"uses the line's baud rate and parity; if no drive should be there, take unit {u.unit} out of "
                   f"the PLC's poll list (each request waits out the master's timeout).")

    def _refused(self, d: Diagnosis) -> list[Finding]:
        by_unit: dict[tuple, list] = {}
        for (name, (unit, *key)), (n, refusals, frames) in self.keys.items():
            refused = sum(refusals.values())
            if n < MIN_REQUESTS or refused < MIN_REQUESTS or refused < REFUSED_SHARE * n:
                continue
            code, _ = refusals.most_common(1)[0]
            by_unit.setdefault((name, unit), []).append((tuple(key), n, refused, code, frames))
        out = []
        for (name, unit), rows in by_unit.items():
            rows.sort(key=lambda r: -r[2])
            what = "; ".join(f"{key_text(k)}: {r} of {n} refused with {c:02X}H" for k, n, r, c, _ in rows[:4])
            more = f" and {len(rows) - 4} more" if len(rows) > 4 else ""
            out.append(Finding(
                "unit_refuses", WARNING, unit=unit, link=name,
                evidence={"requests_refused": sum(r[2] for r in rows), "kinds_of_request": len(rows),
                          "refusals": {key_text(k): {"requests": n, "refused": r, "exception": f"{c:02X}H"}
                                       for k, n, r, c, _ in rows[:8]}},
                frames=[i for r in rows for i in r[4][:2]],
                text=f"The master keeps asking unit {unit} for what it refuses every time: {what}{more}.",
                action="Fix the PLC's request (address, count or function the drive's manual allows; a parameter "
                       "the drive takes only in another mode) or take it out of the poll list."))
        return out
