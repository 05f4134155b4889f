"""Units that do not do what they are asked: unit_silent, unit_refuses, answers_broadcast.

* unit_silent: CRC-good requests to a unit (their address byte is checked, so the unit is the one the
  master meant), and over the whole span no answer from it, good or damaged; or, for a unit that does
  answer, stretches of time in which it answered none (at least SILENT_REQUESTS requests over SILENT_S
  seconds: more than a power blink or a run of lost answers), each an episode;
* unit_refuses: the master keeps sending a unit one request it answers with an exception every time
  (an address it does not have, a write it does not allow in this mode), over the capture or in stretches
  of it (judged in windows from its first refusal on: each stretch an episode); requests refused now and
  then (busy) are no finding;
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
from sniffer.diagnose.episodes import Episode, Windows, merged
from sniffer.diagnose.finding import Finding

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MIN_REQUESTS = 3
MIN_SPAN_NS = 1_000_000_000
REFUSED_SHARE = 0.5  # of one request's tries answered with an exception
STRETCH_SHARE = 0.8  # ... or of its tries in a stretch of time (an episode: refused nearly every time then)
MAX_KEYS = 4096
_ECHOES = frozenset((0x05, 0x06, 0x08))
SILENT_REQUESTS = 8  # unanswered requests in a row, at least ...
SILENT_S = 3.0  # ... over this long: a unit that stopped answering for a while


class UnitsGroup(Group):
    def __init__(self) -> None:
        self.plain_by: Counter = Counter()  # (link, unit) -> CRC-good answers naming it to no request known, not echoes
        # (link, unit, key) -> [requests, refusals Counter, frames, Windows of its answers from its first refusal on]
        self.keys: dict[tuple, list] = {}
        self.broadcast: dict[tuple, list] = {}  # (link, unit) -> [count, frames]
        # (link, unit) -> [first request's t, last request's end, requests, first request's frame] since its
        # last answer; and the stretches that were long enough (first and last kept, all counted)
        self.quiet: dict[tuple, list] = {}
        self.gaps: dict[tuple, list] = {}
        self.gap_count: Counter = Counter()

    def _answered(self, link: Link, unit: int) -> None:
        run = self.quiet.pop((link.name, unit), None)
        if run is not None and run[2] - 1 >= SILENT_REQUESTS:
            # the last request of the run is the one answered now: the silence ended with the one before
            self._gap(link, unit, run[0], run[4], run[2] - 1, run[3])

    def _gap(self, link: Link, unit: int, t0: int, t1: int, n: int, frame: int) -> None:
        if t1 - t0 < SILENT_S * 1e9:
            return
        k = (link.name, unit)
        gaps = self.gaps.setdefault(k, [])
        self.gap_count[k] += 1
        gaps.append((t0, t1, n, frame))
        if len(gaps) > 6:
            del gaps[3]

    def other(self, f, link: Link, unit: Unit | None, codes: frozenset) -> None:
        self.noise(f, link, codes)

    def noise(self, f, link: Link, codes: frozenset) -> None:
        if link.slot is not None:
            self._answered(link, link.slot.unit)  # a damaged burst where its answer was due: it answered
        elif self.quiet and link.last_role == "request" and link.last_unit is not None and len(f.raw) >= 3:
            self._answered(link, link.last_unit.unit)  # something answered it, damaged past telling: not silence

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if self.quiet:
            who = unit.unit if unit is not None else f.unit if f.crc_ok else None
            if who is not None and not (req is not None and f.function in _ECHOES and f.raw == req[1].raw):
                # (an "answer" byte for byte its request is the master's retry of it, not an answer)
                self._answered(link, who)
        if req is not None and f.crc_ok and not f.exception:
            e = self.keys.get((link.name, req[2]))
            if e is not None and e[3] is not None:
                e[3].add(f.t_ns)  # answered, not refused: a chance in time for the key's refusals
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
                if e[3] is None:
                    e[3] = Windows()
                e[3].add(f.t_ns, True)
                if len(e[2]) < 8:
                    e[2].append(f.index)

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if f.unit:
            run = self.quiet.get((link.name, f.unit))
            if run is None:
                self.quiet[(link.name, f.unit)] = [f.t_ns, f.t_end_ns, 1, f.index, f.t_end_ns]
            else:
                run[4] = run[1]  # the end of the request before: where a silence ends if this one is answered
                run[1] = f.t_end_ns
                run[2] += 1
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
            e = self.keys[k] = [0, Counter(), [], None]
        return e

    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for link in d.links.values():
            for u in link.units.values():
                if u.unit == 0:
                    continue
                f = self._silent(d, link, u)
                if f is None:
                    f = self._stretches(d, link, u)
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
            episodes=[Episode(d.seconds(u.first_ns), d.seconds(u.last_ns), u.requests, "requests unanswered")],
            evidence={"requests": u.requests, "retries": u.retries, "answers": 0, "span_s": round(span, 1)},
            text=f"Unit {u.unit} never answered: {u.requests} requests to it ({u.retries} of them retries) over "
                 f"{span:.1f} s got no response, good or damaged.{echoes}",
            action=f"Check that a drive is set to address {u.unit}, is powered and wired to this line (A/B), and "
                   f"uses the line's baud rate and parity; if no drive should be there, take unit {u.unit} out of "
                   f"the PLC's poll list (each request waits out the master's timeout).")

    def _stretches(self, d: Diagnosis, link: Link, u: Unit) -> Finding | None:
        """A unit that answers, silent for stretches: one episode each (the open one runs to the end)."""
        k = (link.name, u.unit)
        gaps = list(self.gaps.get(k, ()))
        count = self.gap_count.get(k, 0)
        run = self.quiet.get(k)
        if run is not None and run[2] >= SILENT_REQUESTS and run[1] - run[0] >= SILENT_S * 1e9:
            gaps.append((run[0], run[1], run[2], run[3]))
            count += 1
        if not gaps:
            return None
        eps = [Episode(d.seconds(a), d.seconds(b), n, "requests unanswered") for a, b, n, _ in gaps]
        silent_s = sum(e.to_s - e.from_s for e in eps)
        longest = max(eps, key=lambda e: e.to_s - e.from_s)
        times = "once" if count == 1 else f"{count} times"
        end = " and was still silent at the end of the capture" if run is not None and gaps[-1][0] == run[0] else ""
        return Finding(
            "unit_silent", ERROR, unit=u.unit, link=link.name, t_start=eps[0].from_s, t_end=eps[-1].to_s,
            frames=[g[3] for g in gaps], episodes=eps, episode_count=count,
            evidence={"silent_stretches": count, "requests_unanswered": sum(g[2] for g in gaps),
                      "longest_s": round(longest.to_s - longest.from_s, 1), "answers_outside": u.answers},
            text=f"Unit {u.unit} stopped answering {times} ({silent_s:.0f} s in all, the longest from "
                 f"{longest.from_s:.1f} s to {longest.to_s:.1f} s){end}; it answers before and after, so the "
                 f"master's data from it is stale meanwhile.",
            action=f"Check unit {u.unit}'s power supply and connector (a loose A/B wire or a brown-out makes it drop "
                   f"out and come back), and whether it was reset or its communication parameters changed then.")

    def _refused(self, d: Diagnosis) -> list[Finding]:
        by_unit: dict[tuple, list] = {}
        for (name, (unit, *key)), (n, refusals, frames, w) in self.keys.items():
            refused = sum(refusals.values())
            if n < MIN_REQUESTS or refused < MIN_REQUESTS:
                continue
            every = w.episodes(d.seconds, "requests refused") if w is not None else []
            # refused every time over the capture, or in stretches of it (each stretch refused nearly every time)
            eps = [e for e in every if e.count >= MIN_REQUESTS and e.count >= STRETCH_SHARE * e.chances]
            if refused < REFUSED_SHARE * n and not eps:
                continue
            code, _ = refusals.most_common(1)[0]
            by_unit.setdefault((name, unit), []).append((tuple(key), n, refused, code, frames, (eps, every)))
        out = []
        for (name, unit), rows in by_unit.items():
            rows.sort(key=lambda r: -r[2])
            link = d.links[name]
            what = "; ".join(f"{key_text(k)}{_register(link, unit, k)}: {r} of {n} refused with {c:02X}H"
                             for k, n, r, c, _, _ in rows[:4])
            more = f" and {len(rows) - 4} more" if len(rows) > 4 else ""
            out.append(Finding(
                "unit_refuses", WARNING, unit=unit, link=name,
                evidence={"requests_refused": sum(r[2] for r in rows), "kinds_of_request": len(rows),
                          "refusals": {key_text(k) + _register(link, unit, k):
                                       {"requests": n, "refused": r, "exception": f"{c:02X}H"}
                                       for k, n, r, c, _, _ in rows[:8]}},
                frames=[i for r in rows for i in r[4][:2]], episodes=_when(rows),
                text=f"The master keeps asking unit {unit} for what it refuses every time: {what}{more}.",
                action="Fix the PLC's request (address, count or function the drive's manual allows; a parameter "
                       "the drive takes only in another mode) or take it out of the poll list."))
        return out


def _when(rows: list) -> list[Episode]:
    """A unit's refusals in time: the stretches its requests were refused nearly every time, or (a request
    refused most of the time, no stretch of it every time) all its refusals."""
    return merged([e for r in rows for e in r[5][0]]) or merged([e for r in rows for e in r[5][1]])


def _register(link: Link, unit: int, key: tuple) -> str:
    """' (Cn-27 Communication timeout)': the first register a request names, as the unit's map names it."""
    reg = link.registry
    fc, addr = key[0], key[1]
    if reg is None or addr is None or fc not in (3, 4, 6, 16):
        return ""
    try:
        row = reg.decoders.get(reg.model_for(unit)).map.registers.get(addr)
    except AttributeError:
        return ""
    if row is None or not row.name:
        return ""
    return f" ({row.id + ' ' if row.id else ''}{row.name})"
