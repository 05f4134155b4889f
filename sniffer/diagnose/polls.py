"""How the master uses the line: poll_cycle, poll_redundant (both info: what to know, not what is wrong).

* poll_cycle: the cycle (the median interval of the most frequent request), how much of the line the
  exchanges take (their characters, the answers' turnarounds and a t3.5 silence after each frame) and
  the room left at this baud: how many more units polled alike fit in the cycle;
* poll_redundant: reads whose answer never (or almost never) changes, asked often: their share of the
  line could go to something else (read them less often, or after a write).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.diagnose.codesets import RETRY
from sniffer.codes import INFO
from sniffer.analysis.diff import key_text
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding
from sniffer.diagnose.stats import Quantiles

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MAX_TYPES = 256
MIN_CYCLES = 20
REDUNDANT_READS = 50
REDUNDANT_RATE = 1.0  # reads a second


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
        self.turnaround_ns: dict[str, int] = {}

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
        if f.latency_ms is not None:
            self.turnaround_ns[link.name] = self.turnaround_ns.get(link.name, 0) + int(f.latency_ms * 1e6)
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
        frames = link.frames
        used_ns = link.busy_ns + self.turnaround_ns.get(link.name, 0) + frames * link.t35_ns
        share = used_ns / max(span_s * 1e9, 1)
        units = sorted({k[0] for k in types if k[0]})
        per_unit = share / max(len(units), 1)
        room = int((1 - share) / per_unit) if per_unit > 0 and share < 1 else 0
        fastest = cycle * share
        return Finding(
            "poll_cycle", INFO, link=link.name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
            evidence={"cycle_ms": round(cycle, 1), "units_polled": len(units), "line_busy_share": round(share, 3),
                      "baud": link.line.baud, "room_for_units": room, "shortest_cycle_ms": round(fastest, 1)},
            frames=[top.first_index],
            text=f"The master polls {len(units)} unit(s) in a cycle of {cycle:.0f} ms; the exchanges take "
                 f"{share:.0%} of the line at {link.line.baud} baud: room for about {room} more unit(s) polled "
                 f"alike, or a cycle of about {fastest:.0f} ms for these.",
            action="Nothing to fix; before adding drives or polls, keep the line below about 70 % busy (retries and "
                   "slow answers need the rest).")

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
        return Finding(
            "poll_redundant", INFO, link=link.name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
            evidence={"reads": {text: {"per_s": round(t.n / span_s, 2), "changes": t.changes}
                                for _, text, t in rows[:8]},
                      "line_share": round(share, 3)},
            frames=[t.first_index for _, _, t in rows[:4]],
            text=f"{len(rows)} read(s) asked often never change their answer ({', '.join(x for _, x, _ in rows[:3])}"
                 f"{' ...' if len(rows) > 3 else ''}): {share:.1%} of the line.",
            action="Read those less often (or once after a write): the time goes to the values that move.")
