"""How the master uses the line: poll_cycle, poll_redundant (both info: what to know, not what is wrong).

* poll_cycle: the cycle (the median interval of the most frequent request), how much of the line the
  exchanges take (their characters, the answers' turnarounds and the silence before each other frame, up
  to t3.5) and the room left at this baud: how many more units polled alike fit in the cycle.  A line
  that is full (FULL) has no time for a retry or a slow answer: said, with what to do, and a warning
  where retries or unanswered requests show it already stretching the cycle;
* poll_redundant: reads whose answer never (or almost never) changes, asked often: their share of the
  line could go to something else (read them less often, or after a write).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.diagnose.codesets import RETRY
from sniffer.codes import INFO, WARNING
from sniffer.analysis.diff import key_text
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding, count_of
from sniffer.diagnose.episodes import Episode
from sniffer.diagnose.stats import Quantiles

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MAX_TYPES = 256
MIN_CYCLES = 20
REDUNDANT_READS = 50
REDUNDANT_RATE = 1.0  # reads a second
BUSY = 0.7  # of the line: above, retries and slow answers start to stretch the cycle
FULL = 0.95  # of the line: no room for anything more


class _Type:
    __slots__ = ("n", "last", "intervals", "answers", "changes", "digest", "bytes", "first_index")

    def __init__(self) -> None:
        self.n = 0
        self.last: int | None = None
        self.intervals = Quantiles()
        self.answers = 0
        self.changes = 0
        self.digest: int | None = None
        self.bytes = 0
        self.first_index = -1


class PollsGroup(Group):
    def __init__(self) -> None:
        self.types: dict[str, dict[tuple, _Type]] = {}

    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if codes and not RETRY.isdisjoint(codes):
            return
        types = self.types.get(link.name)
        if types is None:
            types = self.types[link.name] = {}
        t = types.get(key)
        if t is None:
            if len(types) >= MAX_TYPES:
                return
            t = types[key] = _Type()
            t.first_index = f.index
        t.n += 1
        if t.last is not None:
            t.intervals.add((f.t_ns - t.last) / 1e6)
        t.last = f.t_ns
        t.bytes += len(f.raw)

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if req is None or not f.crc_ok or f.exception or f.function not in (1, 2, 3, 4):
            return
        types = self.types.get(link.name)
        t = types.get(req[2]) if types is not None else None
        if t is None:
            return
        t.answers += 1
        t.bytes += len(f.raw)
        digest = hash(f.adu[2:])
        if t.digest is not None and digest != t.digest:
            t.changes += 1
        t.digest = digest

    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for name, types in self.types.items():
            link = d.links[name]
            if link.first_ns is None or not types:
                continue
            span_s = (link.last_ns - link.first_ns) / 1e9
            f = self._cycle(d, link, types, span_s)
            if f is not None:
                out.append(f)
            f = self._redundant(d, link, types, span_s)
            if f is not None:
                out.append(f)
        return out

    def _cycle(self, d: Diagnosis, link: Link, types: dict, span_s: float) -> Finding | None:
        top = max(types.values(), key=lambda t: t.n)
        cycle = top.intervals.median() if top.intervals.n else None
        if cycle is None or cycle <= 0 or span_s * 1e3 / cycle < MIN_CYCLES or link.line is None:
            return None
        used_ns = link.busy_ns + link.gaps_ns
        share = used_ns / max(span_s * 1e9, 1)
        units = sorted({k[0] for k in types if k[0]})
        per_unit = share / max(len(units), 1)
        room = int((1 - share) / per_unit) if per_unit > 0 and share < 1 else 0
        fastest = cycle * share
        retried = sum(u.retries + u.no_response for u in link.units.values() if u.answered)
        ev = {"cycle_ms": round(cycle, 1), "units_polled": len(units), "line_busy_share": round(min(share, 1.0), 3),
              "baud": link.line.baud, "room_for_units": room, "shortest_cycle_ms": round(fastest, 1)}
        severity = INFO
        if share >= FULL:
            ev["retries_and_unanswered"] = retried
            severity = WARNING if retried else INFO
            said = (f"the exchanges fill {min(share, 1.0):.0%} of the line at {link.line.baud} baud: no room for "
                    f"another unit, and a retry or a slow answer stretches the cycle"
                    + (f" (it did: {retried} retries or unanswered requests)" if retried else ""))
            action = ("Make room before anything is added: lengthen the cycle, read the slow-changing values less "
                      "often, raise the baud rate (every drive and the PLC together), or split the drives over two "
                      "lines.")
        elif share >= BUSY:
            said = (f"the exchanges take {share:.0%} of the line at {link.line.baud} baud: room for about "
                    f"{count_of(room, 'more unit', 'more units')} polled alike, little for retries and slow answers")
            action = ("Before adding drives or polls, lengthen the cycle or raise the baud rate: above about 70 % busy "
                      "a retry or a slow answer delays the whole cycle.")
        else:
            said = (f"the exchanges take {share:.0%} of the line at {link.line.baud} baud: room for about "
                    f"{count_of(room, 'more unit', 'more units')} polled alike, or a cycle of about {fastest:.0f} ms "
                    f"for these")
            action = ("Nothing to fix; before adding drives or polls, keep the line below about 70 % busy (retries and "
                      "slow answers need the rest).")
        return Finding(
            "poll_cycle", severity, link=link.name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
            evidence=ev, frames=[top.first_index],
            text=f"The master polls {count_of(len(units), 'unit')} in a cycle of {cycle:.0f} ms; {said}.",
            action=action)

    def _redundant(self, d: Diagnosis, link: Link, types: dict, span_s: float) -> Finding | None:
        if span_s <= 0:
            return None
        rows = []
        for (unit, fc, addr, qty), t in types.items():
            if t.answers < REDUNDANT_READS or t.n / span_s < REDUNDANT_RATE or t.changes > t.answers // 100:
                continue
            rows.append((t.bytes, f"u{unit} {key_text((fc, addr, qty))}", t))
        if not rows:
            return None
        rows.sort(key=lambda r: -r[0])
        share = sum(b for b, _, _ in rows) * link.char_ns / max(span_s * 1e9, 1)
        t0, t1 = d.seconds(link.first_ns), d.seconds(link.last_ns)
        return Finding(
            "poll_redundant", INFO, link=link.name, t_start=t0, t_end=t1,
            # the reads all along: one episode (a read whose answer changed would not be one of these)
            episodes=[Episode(t0, t1, sum(t.n for _, _, t in rows), "reads whose answer never changed")],
            evidence={"reads": {text: {"per_s": round(t.n / span_s, 2), "changes": t.changes}
                                for _, text, t in rows[:8]},
                      "line_share": round(share, 3)},
            frames=[t.first_index for _, _, t in rows[:4]],
            text=f"{count_of(len(rows), 'read')} asked often never change their answer "
                 f"({', '.join(x for _, x, _ in rows[:3])}{' ...' if len(rows) > 3 else ''}): {share:.1%} of the line.",
            action="Read those less often (or once after a write): the time goes to the values that move.")
