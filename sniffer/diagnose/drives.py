"""What the drives report: drive_fault.

* drive_fault: the drive's model reports a trip (model.fault: its fault register, with the manual's
  text).  One trip is one episode: from the first answer that reports it to the first answer of the
  same read that no longer does; meanwhile the master's writes to the drive are counted (a run command
  written into a fault does nothing) and the last write before the episode ends is named (the reset);
  where the drive's answers are mostly lost (cut, damaged: the fault register cannot be read), the master's
  own writes still say it: each write that sets a bit its model names a fault reset is a trip the master
  saw and reset (`_blind_trips`; a master that resets drives whose answers say nothing is not judged);
(noise_correlated_with_load, the line's damage against what the drives do: correlate.py)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.codes import ERROR
from sniffer.diagnose.codesets import FAULT
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.episodes import Episode
from sniffer.diagnose.finding import Finding, count_of

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

_WRITES = frozenset((0x05, 0x06, 0x0F, 0x10))
MIN_RESETS = 2  # fault resets written to a drive whose answers are lost: a trip seen by the master only
LOST = 0.5  # of a drive's answers damaged: its fault register cannot be read



class _Episode:
    __slots__ = ("text", "key", "start_ns", "end_ns", "first", "writes", "written", "last_write", "closed", "seen")

    def __init__(self, text: str, key, t: int, index: int) -> None:
        self.text = text
        self.key = key
        self.start_ns = t
        self.end_ns = t
        self.first = index
        self.writes = 0
        self.written: set[str] = set()
        self.last_write: tuple[int, str] | None = None
        self.closed = False
        self.seen = 0  # answers that reported it


class DrivesGroup(Group):
    def __init__(self) -> None:
        self.open: dict[tuple, dict[str, _Episode]] = {}  # (link, unit) -> fault text -> episode
        self.done: dict[tuple, list[_Episode]] = {}  # (link, unit, text) -> episodes (first and last kept)
        self.counts: dict[tuple, int] = {}
        self.reset_bits: dict[tuple, dict[int, int]] = {}  # (link, model) -> register -> its fault-reset bits
        self.resets: dict[tuple, list] = {}  # (link, unit) -> [count, [(t_ns, frame), ...] first and last kept]

    # ------------------------------------------------------------ frames
    def request(self, f, link: Link, unit: Unit, codes: frozenset, key: tuple) -> None:
        if f.function in _WRITES and f.model is not None and f.model != "generic":
            self._reset(f, link, unit)
        if self.open and f.function in _WRITES:
            eps = self.open.get((link.name, unit.unit))
            if eps:
                names = [p.get("name", "").split(" (")[0] for p in f.points[:4]] if f.points else []
                for e in eps.values():
                    e.writes += 1
                    e.written.update(n for n in names if n)
                    e.last_write = (f.index, _short(f.summary))

    def _reset(self, f, link: Link, unit: Unit) -> None:
        """A write that sets a fault-reset bit (as the model's map names the bits of the register written)."""
        bits = self.reset_bits.get((link.name, f.model))
        if bits is None:
            bits = self.reset_bits[(link.name, f.model)] = _reset_bits(link, f.model)
        if not bits or not f.points:
            return
        for p in f.points:
            mask = bits.get(p.get("address"))
            raw = p.get("raw")
            if mask and isinstance(raw, int) and raw & mask:
                x = self.resets.setdefault((link.name, unit.unit), [0, []])
                x[0] += 1
                x[1].append((f.t_ns, f.index))
                if len(x[1]) > 6:
                    del x[1][3]  # the first three and the latest ones
                return

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if unit is None or not f.crc_ok or (f.model is None or f.model == "generic") and not self.open and not codes:
            return
        key = (link.name, unit.unit)
        if codes and not FAULT.isdisjoint(codes):
            self._faults(f, link, key, unit)
        elif key in self.open:
            self._maybe_close(f, link, key)

    def _faults(self, f, link: Link, key: tuple, unit: Unit) -> None:
        got = link.request_of(f)
        rk = got[2] if got is not None else None
        eps = self.open.setdefault(key, {})
        seen = set()
        for a in f.annotations:
            if a.code not in FAULT:
                continue
            text = _without_register(a.detail.removeprefix("fault: "))
            seen.add(text)
            e = eps.get(text)
            if e is None:
                e = eps[text] = _Episode(text, rk, f.t_ns, f.index)
            e.end_ns = f.t_end_ns
            e.seen += 1
        for text in [t for t, e in eps.items() if t not in seen and e.key == rk]:
            self._close(key, eps.pop(text), f.t_ns)

    def _maybe_close(self, f, link: Link, key: tuple) -> None:
        got = link.request_of(f)
        if got is None:
            return
        rk = got[2]
        eps = self.open[key]
        for text in [t for t, e in eps.items() if e.key == rk]:
            self._close(key, eps.pop(text), f.t_ns)

    def _close(self, key: tuple, e: _Episode, t: int) -> None:
        if e.seen < 2 and not e.writes:
            return  # one answer said so, the next not, and nobody reset it: a damaged frame whose CRC held by chance
        e.end_ns = t
        e.closed = True
        k = (*key, e.text)
        self.counts[k] = self.counts.get(k, 0) + 1
        lst = self.done.setdefault(k, [])
        lst.append(e)
        if len(lst) > 6:
            del lst[3]  # the first three and the latest ones

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        out = self._trips(d)
        return out + self._blind_trips(d, {(f.link, f.unit) for f in out})

    def _blind_trips(self, d: Diagnosis, said: set) -> list[Finding]:
        """Trips only the master's fault resets show: the drive's answers, which would name the fault, are mostly
        lost (a driver that cuts them, damage); each reset is a trip the master saw and acknowledged."""
        out = []
        for (name, unit), (n, seen) in sorted(self.resets.items()):
            u = d.links[name].units.get(unit)
            if n < MIN_RESETS or (name, unit) in said or u is None:
                continue
            # its answers lost: damaged, or so broken (a USB adapter's reads split them) that none paired
            answers = max(u.requests, u.answers + u.garbled)
            lost = u.damaged_answers + max(u.garbled, u.no_response)
            if not answers or lost < LOST * answers:
                continue  # its answers are read: a reset with no fault read is the PLC's habit, not a trip
            t0, t1 = d.seconds(seen[0][0]), d.seconds(seen[-1][0])
            out.append(Finding(
                "drive_fault", ERROR, unit=unit, link=name, t_start=t0, t_end=t1, episode_count=n,
                evidence={"fault_resets_written": n, "answers": answers, "answers_lost": lost,
                          "answers_lost_share": round(lost / answers, 3)},
                episodes=[Episode(d.seconds(t), d.seconds(t), 1, f"fault reset #{i}") for t, i in seen],
                frames=[i for _, i in seen[:4]],
                text=f"Unit {unit} trips: the master wrote a fault reset to it {count_of(n, 'time')} (first at "
                     f"{t0:.1f} s); which fault cannot be read: {lost / answers:.0%} of its answers are lost ({lost} "
                     f"of {answers} damaged or missing).",
                action=f"Read unit {unit}'s fault history on its keypad (the bus lost the answers that say it), "
                       f"remove the cause, and fix what damages its answers first."))
        return out

    def _trips(self, d: Diagnosis) -> list[Finding]:
        """One finding per drive: its faults (the manual's text), each episode from when to when, what the
        master wrote meanwhile, and the write that reset it."""
        by_unit: dict[tuple, list] = {}
        for (name, unit, text), eps in self.done.items():
            by_unit.setdefault((name, unit), []).append((text, list(eps), self.counts[(name, unit, text)]))
        for (name, unit), eps in self.open.items():
            for text, e in eps.items():
                rows = by_unit.setdefault((name, unit), [])
                row = next((r for r in rows if r[0] == text), None)
                if row is None:
                    rows.append((text, [e], 1))
                else:
                    row[1].append(e)
                    rows[rows.index(row)] = (text, row[1], row[2] + 1)
        out = []
        for (name, unit), rows in sorted(by_unit.items(), key=str):
            episodes = sorted((e for _, eps, _ in rows for e in eps), key=lambda e: e.start_ns)
            n = sum(c for _, _, c in rows)
            writes = sum(e.writes for e in episodes)
            written = sorted({w for e in episodes for w in e.written})[:4]
            resets = [e.last_write for e in episodes if e.closed and e.last_write]
            still = [e for e in episodes if not e.closed]
            faults = ", ".join(f"{t} ({c}x)" if c > 1 else t for t, _, c in sorted(rows, key=lambda r: -r[2]))
            ev = {"trips": n, "faults": {t: c for t, _, c in rows},
                  "tripped_s": round(sum(e.end_ns - e.start_ns for e in episodes) / 1e9, 2), "writes_during": writes}
            if written:
                ev["written_during"] = written
            tail = "; still tripped at the end of the capture" if still else ""
            reset = f"; reset by writes such as #{resets[-1][0]} ({resets[-1][1]})" if resets else ""
            during = f"; the master wrote to it {writes} times while tripped ({', '.join(written)})" if writes else ""
            first, last = episodes[0], episodes[-1]
            out.append(Finding(
                "drive_fault", ERROR, unit=unit, link=name, t_start=d.seconds(first.start_ns),
                t_end=d.seconds(last.end_ns), evidence=ev, episode_count=n,
                episodes=[Episode(d.seconds(e.start_ns), d.seconds(e.end_ns), max(e.writes, 0),
                                  _trip_words(e)) for e in episodes],
                frames=[e.first for e in episodes[:4]] + [r[0] for r in resets[:2]],
                text=f"Unit {unit} tripped {count_of(n, 'time')}: {faults}; first at {d.seconds(first.start_ns):.1f} s"
                     f"{during}{reset}{tail}.",
                action=f"Look up {rows[0][0].split(' (')[0]} (and the others) in the drive's manual and remove the "
                       f"cause; a PLC that resets the drive and runs it again at once only repeats the trip."))
        return out


def _reset_bits(link: Link, model: str) -> dict[int, int]:
    """register -> the bits its map names a fault reset (one-bit fields named "... reset"), in the model's map."""
    try:
        m = link.decoder(model).map
        rows = m.registers.items()
    except AttributeError:
        return {}
    out = {}
    for addr, r in rows:
        for fdef in m.bits.get(r.bits or "", []) if r.bits else ():
            if fdef["lo"] == fdef["hi"] and "reset" in fdef["name"].lower():
                out[addr] = out.get(addr, 0) | 1 << fdef["lo"]
    return out


def _trip_words(e: _Episode) -> str:
    """What an episode's count counts: the master's writes while tripped, the fault and its reset."""
    reset = f", reset by #{e.last_write[0]}" if e.closed and e.last_write else (
        "" if e.closed else ", still tripped at the end")
    return f"writes while tripped; {_short(e.text, 40)}{reset}"


def _short(text: str, n: int = 60) -> str:
    return text if len(text) <= n else text[: n - 3].rstrip() + "..."


def _without_register(detail: str) -> str:
    """'OL1 — Motor overload (Fault bits (low))' -> 'OL1 — Motor overload': the register's name goes."""
    if not detail.endswith(")"):
        return detail
    depth = 0
    for i in range(len(detail) - 1, -1, -1):
        depth += {")": 1, "(": -1}.get(detail[i], 0)
        if depth == 0:
            return detail[:i].rstrip() or detail
    return detail
