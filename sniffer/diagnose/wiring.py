"""The line's electrics: driver_enable_late, driver_disable_early, bus_unbiased.

What the framer keeps on each frame says which byte suffered: a UART flag's span, and for a CRC-bad
frame the one byte that explains the CRC (modbus.crc.one_byte: the first or a CRC byte).  The answers
are counted per unit they answer (the pairer pairs an answer whose address alone is damaged with its
request), so a unit's damaged first bytes are its own, however the address came out:

* driver_enable_late: one unit's answers lose their first byte (a wrong address, a framing flag) and
  keep the rest; or, where the receiver found its step again only bytes later, come as damaged bursts in
  its answer slot that start with another address (mostly the same one: the same bits cut each time);
  the other units' answers do not;
* driver_disable_early: one unit's answers lose their last byte (the CRC's high byte), or carry a
  parity / framing flag on it even where the CRC holds (or, cut off the answer by the framer, as a flagged
  byte right after it);
* both driver faults, measured: a logic capture with the slave's driver-enable line (`--de`) puts its
  timing on the frames (de_on_ns: DE rise - first start bit, > 0 late; de_off_ns: DE fall - end of the
  last stop bit, < 0 early); most of a unit's answers on the wrong side make the finding, or back it;
* bus_unbiased: short stray bursts (00H with a framing error, FFH and the like) after transmissions,
  in turnarounds (after requests) and idle gaps, while the frames themselves are intact.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from collections import Counter

from sniffer.diagnose.codesets import UART
from sniffer.codes import ERROR, WARNING
from sniffer.diagnose.episodes import Windows
from sniffer.framing.crc import damaged_byte
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MIN_HITS = 5
MIN_RATE = 0.05  # of a unit's answers
DOMINANT = 0.5  # of its damaged answers
OTHERS_BELOW = 0.2  # the other units' rate, as a share of this unit's
SPARSE_STRAYS = 3  # stray bursts out of an idle line with no frame damage: a biased line makes none
STRAY_RATE = 0.1  # of the transmissions, where damaged frames are about too
JOIN = 4  # windows: a cut on a share of the answers leaves quiet seconds inside its episode
_DE_KINDS = (("driver_enable_late", "on", "late", "turns on after the first start bit"),
             ("driver_disable_early", "off", "early", "turns off before the last stop bit"))
_DIP = frozenset((0xFF << k) & 0xFF for k in range(9))  # 00, 80, C0 ... FE, FF: a floating line's shapes


class _Answers:
    __slots__ = ("answers", "damaged", "first", "last", "addresses", "frames_first", "frames_last", "bursts", "orphans",
                 "w_first", "w_last")

    def __init__(self) -> None:
        self.answers = 0
        self.damaged = 0
        self.first = 0
        self.last = 0
        self.addresses: Counter = Counter()  # what a damaged first byte read as
        self.frames_first: list[int] = []
        self.frames_last: list[int] = []
        self.bursts = 0  # first-byte hits that are damaged bursts (the receiver lost its step for longer)
        self.orphans = 0  # damaged answers to no request known, their address put back by the CRC
        # every answer of the unit in time, and those with the first / the last byte damaged: when it happened
        self.w_first = Windows()
        self.w_last = Windows()


class WiringGroup(Group):
    def __init__(self) -> None:
        self.answers: dict[tuple, _Answers] = {}
        self.strays: dict[str, dict] = {}
        self.de: dict[tuple, dict] = {}  # (link, unit) -> a logic capture's driver-enable times on its answers
        # link -> whether the last answer's CRC held: a flagged byte right after an intact answer is a stray out of
        # the released line (bus_unbiased), not the answer's last byte cut off it
        self.last_ok: dict[str, bool] = {}

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        de_on, de_off = getattr(f, "de_on_ns", None), getattr(f, "de_off_ns", None)
        if (de_on is not None or de_off is not None) and unit is not None:
            self._de(link, unit, de_on, de_off, f.index)
        link.cut = None
        if f.role == "response":
            self.last_ok[link.name] = bool(f.crc_ok)
        if f.crc_ok and not codes:
            if unit is not None:  # a clean answer: counted in its Unit, and a chance in time for its episodes
                a = self._answers(link, unit)
                a.w_first.add(f.t_ns)
                a.w_last.add(f.t_ns)
            return
        if unit is None:
            if f.crc_ok is False and "modbus.crc.one_byte" in codes:
                hit = damaged_byte(f.raw)  # an orphan whose address alone broke: whose it was
                if hit is None or hit[0] != 0 or hit[1] not in link.units or not link.units[hit[1]].present:
                    return
                unit = link.units[hit[1]]
                orphan = True
            else:
                return
        else:
            orphan = False
        a = self._answers(link, unit)
        a.orphans += orphan
        burst = link.slot is unit  # a damaged burst where its answer was due
        if f.crc_ok is False or burst:
            a.damaged += 1
        # a burst in the unit's answer slot that does not start with its address: the start was cut
        first = burst and f.raw[0] != unit.unit
        if first:
            a.bursts += 1
        if not codes and not first:
            a.w_first.add(f.t_ns)
            a.w_last.add(f.t_ns)
            return
        n = len(f.raw)
        last = False
        for x in f.annotations if not burst else ():  # a burst is damaged all over: no one byte is
            if x.code in UART:
                first |= x.start == 0
                last |= x.start == n - 1
            elif x.code == "modbus.crc.one_byte":
                first |= x.start == 0
                last |= x.start == n - 1
        if first or last:
            link.cut = (unit.unit, "first" if first else "last")
        if first:
            a.first += 1
            a.addresses[f.raw[0]] += 1
            if len(a.frames_first) < 8:
                a.frames_first.append(f.index)
        if last:
            a.last += 1
            if len(a.frames_last) < 8:
                a.frames_last.append(f.index)
        a.w_first.add(f.t_ns, first)
        a.w_last.add(f.t_ns, last)

    def _answers(self, link: Link, unit: Unit) -> _Answers:
        a = self.answers.get((link.name, unit.unit))
        if a is None:
            a = self.answers[(link.name, unit.unit)] = _Answers()
        return a

    def _de(self, link: Link, unit: Unit, on: int | None, off: int | None, index: int) -> None:
        """A logic capture's driver-enable times on an answer (Frame.de_on_ns: DE rise - first start bit;
        de_off_ns: DE fall - end of the last stop bit): the direct measure of both driver faults."""
        x = self.de.get((link.name, unit.unit))
        if x is None:
            x = self.de[(link.name, unit.unit)] = {"on": [], "late": 0, "off": [], "early": 0, "f_on": [], "f_off": []}
        if on is not None:
            if len(x["on"]) < 4096:
                x["on"].append(on)
            if on > 0:
                x["late"] += 1
                if len(x["f_on"]) < 8:
                    x["f_on"].append(index)
        if off is not None:
            if len(x["off"]) < 4096:
                x["off"].append(off)
            if off < 0:
                x["early"] += 1
                if len(x["f_off"]) < 8:
                    x["f_off"].append(index)

    def other(self, f, link: Link, unit: Unit | None, codes: frozenset) -> None:
        link.cut = None
        if link.slot is not None:
            self.response(f, link, link.slot, codes, None)

    def noise(self, f, link: Link, codes: frozenset) -> None:
        link.cut = None
        if link.slot is not None:
            self.response(f, link, link.slot, codes, None)
            return
        u = link.last_unit
        if (len(f.raw) == 1 and codes and link.last_role == "response" and u is not None and u.present
                and f.idle_before_ns is not None and f.idle_before_ns < link.char_ns
                and not UART.isdisjoint(codes) and not self.last_ok.get(link.name, False)):
            # a flagged byte glued to an answer: its last byte, cut off it (a framer that keeps a flagged byte out
            # of a CRC-good frame leaves the answer a byte short and this after it)
            a = self._answers(link, u)
            link.cut = (u.unit, "last")
            a.last += 1
            if len(a.frames_last) < 8:
                a.frames_last.append(f.index)
            a.w_last.add(f.t_ns, True)  # (the answer it came off was counted a clean chance: this is its hit)
        s = self.strays.get(link.name)
        if s is None:
            s = self.strays[link.name] = {"short": 0, "bytes": 0, "dip": 0, "flagged": 0, "after_request": 0,
                                         "after_answer": 0, "frames": []}
        if len(f.raw) > 3:
            return
        s["short"] += 1
        s["bytes"] += len(f.raw)
        s["dip"] += sum(1 for b in f.raw if b in _DIP)
        s["flagged"] += sum(1 for a in f.annotations if a.code in UART)
        prev = link.last_role
        if prev == "request":
            s["after_request"] += 1
        elif prev == "response":
            s["after_answer"] += 1
        if len(s["frames"]) < 8:
            s["frames"].append(f.index)

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for field, kind in (("first", "driver_enable_late"), ("last", "driver_disable_early")):
            out += self._driver(d, field, kind)
        out = self._with_de(d, out)
        for link in d.links.values():
            f = self._unbiased(d, link)
            if f is not None:
                out.append(f)
        return out

    def _total(self, d: Diagnosis, name: str, unit: int) -> int:
        """A unit's answers: paired to its requests (damaged too), bursts in its answer slot, orphans whose
        address alone broke."""
        u = d.links[name].units.get(unit)
        a = self.answers.get((name, unit))
        return (u.answers + u.garbled if u is not None else 0) + (a.orphans if a is not None else 0)

    def cut(self, d: Diagnosis) -> set[tuple[str, int, str]]:
        """(link, unit, "first" | "last") of each driver the bytes name (driver_enable_late, _disable_early)."""
        return {(f.link or "", f.unit, field) for field, kind in (("first", "driver_enable_late"),
                                                                   ("last", "driver_disable_early"))
                for f in self._driver(d, field, kind)}

    def _driver(self, d: Diagnosis, field: str, kind: str) -> list[Finding]:
        out = []
        for (name, unit), a in self.answers.items():
            hits = getattr(a, field)
            total = self._total(d, name, unit)
            if hits < MIN_HITS or hits < MIN_RATE * total:
                continue
            a.answers = total
            rate = hits / a.answers
            others = [(self.answers.get((name, u2)), self._total(d, name, u2))
                      for u2, x in d.links[name].units.items() if u2 != unit and x.present]
            o_hits = sum(getattr(o, field) for o, _ in others if o is not None)
            o_damaged = sum(o.damaged for o, _ in others if o is not None)
            o_answers = sum(n for _, n in others)
            o_rate = o_hits / o_answers if o_answers else 0.0
            if o_rate > OTHERS_BELOW * rate:
                continue  # the others' answers suffer too: not this unit's driver
            # most of its damage beyond what every unit's answers suffer (noise on the line) is the one byte
            background = (o_damaged - o_hits) / o_answers * total if o_answers else 0.0
            if hits < DOMINANT * (a.damaged - background):
                continue
            link = d.links[name]
            ev = {"answers": a.answers, f"{field}_byte_damaged": hits, "rate": round(rate, 3),
                  "other_units_rate": round(o_rate, 4), "damaged_answers": a.damaged}
            if field == "first":
                # the unit numbers its damaged first bytes made up (a number of a unit on the line is left out:
                # those frames are counted, but not shown as that unit)
                phantoms = [x for x, _ in a.addresses.most_common() if x not in link.units
                            or not link.units[x].present][:5]
                shown = ", ".join(map(str, phantoms))
                if phantoms:
                    ev["shown_as_units"] = phantoms
                how = []
                if hits - a.bursts:
                    how.append(f"{hits - a.bursts} with the rest intact")
                if a.bursts:
                    how.append(f"{a.bursts} damaged from there on until the receiver found its step again")
                ev["rest_intact"], ev["damaged_bursts"] = hits - a.bursts, a.bursts
                text = (f"Unit {unit}'s transmitter turns on late: {hits} of its {a.answers} answers ({rate:.0%}) "
                        f"arrive with the first byte damaged ({'; '.join(how)})"
                        + (f"; shown as units {shown}, which are unit {unit}" if shown else "")
                        + f"; the other units' answers {o_rate:.1%}.")
                action = (f"Check unit {unit}'s RS-485 driver enable: its direction control (RTS/DE) switches after "
                          f"the first start bit. Set its transmit delay / response delay longer, or fix the "
                          f"adapter's auto-direction; the master drops these answers.")
                frames = a.frames_first
                when = a.w_first.episodes(d.seconds, "answers with the first byte damaged", join=JOIN)
            else:
                text = (f"Unit {unit}'s transmitter turns off early: {hits} of its {a.answers} answers ({rate:.0%}) "
                        f"have their last byte (the CRC's high byte) damaged or flagged; the other units' answers "
                        f"{o_rate:.1%}.")
                action = (f"Check unit {unit}'s RS-485 driver: it releases the line before the last stop bit "
                          f"(direction switched on 'buffer empty' instead of 'transmission complete'); set its "
                          f"line to 2 stop bits or fix its direction control.")
                frames = a.frames_last
                when = a.w_last.episodes(d.seconds, "answers with the last byte damaged", join=JOIN)
            out.append(Finding(kind, ERROR, unit=unit, link=name, t_start=d.seconds(link.first_ns),
                               t_end=d.seconds(link.last_ns), evidence=ev, frames=frames, text=text, action=action,
                               episodes=when))
        return out

    def _with_de(self, d: Diagnosis, out: list[Finding]) -> list[Finding]:
        """The driver-enable times a logic capture measured: added to a driver finding the bytes made, or a
        finding of their own (a driver that is late or early by less than a bit damages no byte yet)."""
        for (name, unit), x in self.de.items():
            for kind, key, bad, label in _DE_KINDS:
                vals, hits = x[key], x[bad]
                if hits < MIN_HITS or hits < 0.5 * len(vals):
                    continue
                med = sorted(vals)[len(vals) // 2] / 1e3
                ev = {f"de_{key}_measured": len(vals), f"de_{bad}": hits, f"de_{key}_median_us": round(med, 1)}
                said = f"the driver-enable line says it {label} on {hits} of {len(vals)} answers (median {med:+.1f} us)"
                frames = x["f_on" if key == "on" else "f_off"]
                f = next((y for y in out if y.kind == kind and y.link == name and y.unit == unit), None)
                if f is not None:
                    f.evidence.update(ev)
                    f.text = f.text.rstrip(".") + f"; {said}."
                    f.frames = sorted(set(f.frames) | set(frames))[:8]
                    continue
                link = d.links[name]
                what = "on" if key == "on" else "off"
                out.append(Finding(
                    kind, ERROR, unit=unit, link=name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
                    evidence=ev, frames=frames,
                    text=f"Unit {unit}'s transmitter turns {what} {'late' if key == 'on' else 'early'}: {said}.",
                    action=f"Check unit {unit}'s RS-485 direction control (DE/RTS): it must enable the driver before "
                           f"the first start bit and hold it past the last stop bit; set its transmit delay, or fix "
                           f"the adapter's auto-direction."))
        return out

    def _unbiased(self, d: Diagnosis, link: Link) -> Finding | None:
        """Stray bursts out of the idle line.  A biased line's idle level is held: it makes none, so even a
        handful (SPARSE_STRAYS) is reported when no frame damage explains them (the rate is stated); with
        damaged frames about, strays must come after a good share of the transmissions (STRAY_RATE)."""
        s = self.strays.get(link.name)
        frames = link.frames - link.noise_frames
        if s is None or frames <= 0 or s["short"] < SPARSE_STRAYS:
            return None
        rate = s["short"] / frames
        floaty = (s["dip"] + s["flagged"]) / max(s["bytes"], 1)
        damaged = link.crc_bad / frames
        if floaty < 0.6 or s["after_request"] < 0.2 * s["short"]:
            return None  # (strays only after answers: a transmitter's own cut-off, not the idle line)
        sparse = link.crc_bad <= max(2, 0.5 * s["short"])  # no damage to speak of: the strays are the line's own
        if not sparse and (rate < STRAY_RATE or damaged > 0.5 * rate or s["short"] < 10):
            return None
        span_h = max((link.last_ns - link.first_ns) / 3.6e12, 1e-9) if link.first_ns is not None else 1e-9
        per_h = s["short"] / span_h
        how = (f"after {rate:.0%} of the transmissions" if rate >= 0.01 else
               f"after {rate:.2%} of the transmissions ({s['short']} in {span_h * 60:.1f} min, about {per_h:,.0f} "
               f"an hour)")
        return Finding(
            "bus_unbiased", WARNING, link=link.name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
            evidence={"stray_bursts": s["short"], "per_frame": round(rate, 4), "per_hour": round(per_h),
                      "bytes_00_ff_or_flagged": round(min(floaty, 1.0), 3), "after_requests": s["after_request"],
                      "after_answers": s["after_answer"], "frames_crc_bad": link.crc_bad},
            frames=s["frames"], episodes=link.damage.episodes(d.seconds, "stray bursts or damaged frames"),
            text=f"The idle line floats: {how} a stray character (00H with a framing error, FFH and the like) comes "
                 f"out of the released line, in turnarounds ({s['after_request']}) and idle gaps "
                 f"({s['after_answer']}), while the frames themselves are "
                 f"{'intact' if link.crc_bad == 0 else 'mostly intact'}. A biased line makes none: it is "
                 f"beginning to float.",
            action="Add fail-safe bias (pull-up on A/D+, pull-down on B/D-, e.g. 680 ohm at one point of the line) and "
                   "check the 120 ohm termination at both ends only.")
