"""Parameters: params_not_saved, eeprom_wear, params_changed.

A drive model whose map names an EEPROM save register ([model] eeprom_save: the TDS-V8's 0500H, and
which parameter groups a save keeps, saves_in_drv / saves_in_prg) tells which writes need a save:

* params_not_saved: an acknowledged write (its answer confirms it: Frame.writes on the answer) to a
  parameter of those groups, and no acknowledged save of the unit after it.  A read-back that no longer
  holds the written value after the unit went silent (a power loss) is the loss itself;
* eeprom_wear: acknowledged saves per hour, and the time a typical 100,000-write EEPROM lasts at that rate;
* params_changed (`--params REFERENCE`: a drive's saved parameter set as CSV, or an earlier capture): the
  values this capture reads (or writes) against the reference's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.codes import ERROR, WARNING
from sniffer.diagnose.episodes import Episode, Windows
from sniffer.diagnose.state import Group, Link, Unit
from sniffer.diagnose.finding import Finding, count_of

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

ENDURANCE = 100_000  # writes a typical EEPROM cell takes
WEAR_YEARS = 10.0  # a save rate that wears it out sooner is a finding
SILENCE_NS = 1_000_000_000  # a unit silent this long while polled: power lost?
RECENT_NS = 5_000_000_000  # an unsaved write this close to the capture's end may be saved just after it
_WRITE_FUNCTIONS = frozenset((0x06, 0x10))


class _UnitParams:
    __slots__ = ("model", "save", "groups", "ids", "saves", "first_save", "last_save", "pending", "written",
                 "reverted", "last_answer", "silences", "save_frames", "first_unsaved", "failed_save", "when")

    def __init__(self) -> None:
        self.model = None
        self.save: int | None = None
        self.groups: tuple[str, ...] = ()
        self.ids: dict[int, str] = {}
        self.saves = 0
        self.first_save: int | None = None
        self.last_save: int | None = None
        self.pending: dict[int, tuple] = {}  # addr -> (t_ns, index, raw, name) of the last unsaved write
        self.written: dict[int, int] = {}  # addr -> how often written unsaved
        self.reverted: list[tuple] = []  # (addr, name, written raw, read raw, index)
        self.last_answer: int | None = None
        self.silences: list[tuple[int, int]] = []
        self.save_frames: list[int] = []
        self.first_unsaved: int | None = None
        self.failed_save: tuple | None = None  # (index, code, name) of a save refused after the unsaved writes
        self.when = Windows()  # its answers in time, the acknowledged saves hit: when it saved so often


class ParamsGroup(Group):
    def __init__(self, reference=None) -> None:
        self.reference = reference  # reference.Reference or None
        self.units: dict[tuple, _UnitParams] = {}
        self.read: dict[tuple, dict] = {}  # (link, unit) -> addr -> (value, text, index) last read or written

    def _u(self, link: Link, unit: int, model: str | None) -> _UnitParams:
        key = (link.name, unit)
        p = self.units.get(key)
        if p is None or (model and p.model != model):  # a guessed model may settle later
            p = self.units[key] = _UnitParams()
            p.model = model
            _bind(p, link, model)
        return p

    def response(self, f, link: Link, unit: Unit | None, codes: frozenset, req) -> None:
        if self.reference is None and (f.model is None or f.model == "generic"):
            return  # no save register to keep count of, no reference to hold values against
        if unit is None or not f.crc_ok or f.index in link.echo_retries:
            return
        p = self._u(link, unit.unit, f.model)
        if p.save is None and self.reference is None:
            return
        if f.exception:  # a refused save: what it kept is the last good one's
            if p.save is not None and p.pending and req is not None and req[2][1] == 0x06 and req[2][2] == p.save:
                p.failed_save = (f.index, str(f.exception.get("code", "")), f.exception.get("name", ""))
            return
        if p.last_answer is not None and f.t_ns - p.last_answer > SILENCE_NS:
            p.silences.append((p.last_answer, f.t_ns))
        p.last_answer = f.t_end_ns
        if p.save is not None:
            p.when.add(f.t_ns)
        if not f.writes:
            return
        if self.reference is not None:
            self._values(f, link, unit.unit)
        if p.save is None:
            return
        write = f.function in _WRITE_FUNCTIONS
        for table, start, raws in f.writes:
            if table != "holding":
                continue
            for k, raw in enumerate(raws):
                addr = start + k
                if write and addr == p.save:
                    self._saved(p, f)
                elif write and p.ids.get(addr, "")[:2] in p.groups:
                    if not p.pending:
                        p.first_unsaved = f.t_ns
                    p.pending[addr] = (f.t_ns, f.index, raw, p.ids[addr], _shown(f, addr, raw))
                    p.written[addr] = p.written.get(addr, 0) + 1
                elif not write and addr in p.pending:
                    t, ix, want, name, shown = p.pending[addr]
                    if raw != want and any(a >= t for a, _ in p.silences) and len(p.reverted) < 16:
                        p.reverted.append((addr, name, shown, _shown(f, addr, raw), f.index))

    def _saved(self, p: _UnitParams, f) -> None:
        p.saves += 1
        if p.first_save is None:
            p.first_save = f.t_ns
        p.last_save = f.t_ns
        p.when.mark(f.t_ns)
        p.pending.clear()
        p.written.clear()
        p.failed_save = None
        if len(p.save_frames) < 4:
            p.save_frames.append(f.index)

    def _values(self, f, link: Link, unit: int) -> None:
        want = self.reference.addresses(link, unit, f.model)
        if not want:
            return
        got = self.read.setdefault((link.name, unit), {})
        for pt in f.points:
            a = pt.get("address")
            if a in want and pt.get("value") is not None:
                got[a] = (pt["value"], pt.get("text") or pt.get("value"), f.index, pt.get("unit") or "")

    # ------------------------------------------------------------ verdicts
    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for (name, unit), p in self.units.items():
            link = d.links[name]
            recent = p.first_unsaved is not None and link.last_ns - p.first_unsaved < RECENT_NS
            if p.reverted or (p.pending and (p.failed_save or not recent)):
                out.append(self._not_saved(d, link, unit, p))
            if p.saves >= 3:
                f = self._wear(d, link, unit, p)
                if f is not None:
                    out.append(f)
        if self.reference is not None:
            out += self.reference.compare(d, self.read)
        return out

    def _not_saved(self, d: Diagnosis, link: Link, unit: int, p: _UnitParams) -> Finding:
        names = sorted({v[3] for v in p.pending.values()} | {r[1] for r in p.reverted})
        writes = sum(p.written.get(a, 0) for a in p.pending) or len(p.reverted)
        first = p.first_unsaved
        ev = {"parameters": names, "unsaved_writes": writes, "saves_after": 0, "save_register": f"{p.save:04X}H"}
        frames = [v[1] for v in p.pending.values()]
        failed = ""
        if p.failed_save is not None:
            ix, code, name = p.failed_save
            code = f"{int(code):02X}H " if code.isdigit() else ""
            failed = f" (the save after them was refused: {code}{name}, #{ix})"
            ev["save_refused"] = f"#{ix}"
            frames.append(ix)
        since = count_of(writes, "write")
        text = (f"Unit {unit}: {', '.join(names[:4])} written and acknowledged ({since} since the last save), "
                f"and no save ({p.save:04X}H) after them{failed}: the drive loses them at its next power cycle.")
        sev = WARNING
        if p.reverted:
            addr, name, want, got, ix = p.reverted[0]
            ev["reverted"] = [{"parameter": n, "written": w, "read_back": g, "frame": i}
                              for _, n, w, g, i in p.reverted]
            silence = next((s for s in p.silences), None)
            when = f" after its {(silence[1] - silence[0]) / 1e9:.1f} s silence (a power loss?)" if silence else ""
            text = (f"Unit {unit} lost unsaved parameters: {name} was written ({want}) and acknowledged, never saved "
                    f"({p.save:04X}H), and reads back {got}{when}.")
            frames.append(ix)
            sev = ERROR
        t0 = d.seconds(first) if first is not None else d.seconds(link.first_ns)
        # one episode: from the first write not saved to the end of the capture (nothing saved them since)
        when = [Episode(t0, d.seconds(link.last_ns), writes, "writes not saved")] if t0 is not None else []
        return Finding("params_not_saved", sev, unit=unit, link=link.name, evidence=ev, frames=frames,
                       t_start=t0, t_end=d.seconds(link.last_ns), text=text, episodes=when,
                       action=f"After the PLC's parameter writes to unit {unit}, write the save command "
                              f"({p.save:04X}H) "
                              f"once (not every cycle), or set the parameters on the drive itself.")

    def _wear(self, d: Diagnosis, link: Link, unit: int, p: _UnitParams) -> Finding | None:
        span_ns = max(link.last_ns - (link.first_ns or 0), 1)
        if span_ns < 10_000_000_000:
            return None
        per_hour = p.saves / (span_ns / 3.6e12)
        hours = ENDURANCE / per_hour
        years = hours / (24 * 365)
        if years >= WEAR_YEARS:
            return None
        lasts = f"{hours:.1f} hours" if hours < 48 else f"{hours / 24:.1f} days" if years < 1 else f"{years:.1f} years"
        return Finding(
            "eeprom_wear", ERROR if years < 1 else WARNING, unit=unit, link=link.name,
            t_start=d.seconds(p.first_save), t_end=d.seconds(p.last_save), frames=p.save_frames,
            episodes=p.when.episodes(d.seconds, "saves"),
            evidence={"saves": p.saves, "span_s": round(span_ns / 1e9, 1), "saves_per_hour": round(per_hour, 1),
                      "endurance_writes": ENDURANCE, "years_to_endurance": round(years, 3)},
            text=f"Unit {unit}'s parameters are saved to EEPROM {per_hour:.0f} times an hour ({p.saves} saves in "
                 f"{span_ns / 1e9:.0f} s): a typical {ENDURANCE:,}-write EEPROM lasts {lasts} at this rate "
                 f"(running day and night).",
            action=f"Write the save command ({p.save:04X}H) only after a parameter actually changed, not every cycle; "
                   f"setpoints and run commands need no save.")


def _bind(p: _UnitParams, link: Link, model: str | None) -> None:
    """The save register of the unit's model (the one its frame was decoded with: the registry's naming now may be
    another part's of the capture), the parameter groups a save keeps, and each register's id."""
    try:
        regmap = link.decoder(model).map
    except AttributeError:
        return
    save = regmap.model.eeprom_save
    if save is None:
        return
    p.save = save.addr
    groups = set(save.saves_in_drv) | set(save.saves_in_prg)
    p.groups = tuple(sorted(groups))
    p.ids = {r.addr: r.id for r in regmap.registers.values() if r.id}


def _shown(f, addr: int, raw: int) -> str:
    """A register's value as the frame's points show it ('30.0 Hz'), else its raw number."""
    for pt in f.points:
        if pt.get("address") == addr:
            v, unit = pt.get("value"), pt.get("unit") or ""
            return f"{v} {unit}".strip() if v is not None else str(raw)
    return str(raw)
