"""Guess a unit's drive model from how it answers, on evidence only that model would give.

A wrong name is worse than none (an energy meter renamed "Parameter 7-01"), so a
guess needs evidence a generic device would not produce, per unit and model:

  * a vendor exception code (outside Modbus's 01H-0BH) that only this model's map
    defines: weight 3 (SPL 51H-55H, TDS-V8 21H/22H);
  * a read answered with a value that fits a narrow rule of a register only this
    model's map has, outside the common block 0000H-00FFH (which any device
    answers): a non-zero value in its enum, a non-zero status word that sets no bit
    the manual calls unused: weight 2 per register; a value inside a min..max of at
    most 256 steps: weight 1 per register, 2 in all (a setting's small integer fits
    many ranges; 0 fits nearly every table, so it says nothing);
  * a read of registers only this model's map has, without such a value: weight 1,
    and all of them together count 1 (a device with a big register space answers
    addresses any one map happens to hold);
  * answers that fit the map at all: weight 1, once, and only beside a vendor
    exception (a 52H from a unit whose answers SPL's map holds is SPL's; from a
    unit that answers nothing SPL has it is a stranger's code).
A write's echo is no evidence for a model (any device echoes), only against it:
an echoed write to a register its map calls read-only rules the model out.
Against it:
  * a value the map rules out (outside an enum or min..max, a status word with a
    bit the manual calls unused set): -2 per register (a meter's float32 words
    in a drive's status block);
  * what the model cannot do rules it out for the unit: a normal answer to a
    function code the model does not implement (a meter's 04H), to a register the
    map does not have, to more registers or a longer frame than the manual allows;
    an exception code the map does not define (gateway codes 0AH/0BH aside); a unit
    address the model cannot have.
The unit is named once a model that is not ruled out reaches SCORE (4) and no
other model that is not ruled out has evidence of its own: e.g. two described
registers only it has, or a vendor exception plus an answer its map fits.  A
unit with no evidence of its own that is polled like a unit named from its own
evidence (at least two of the same requests answered, half of all it answered),
not ruled out for that model (no value its map rules out) and showing its shape
(a non-zero status word or code that fits the map's bits or enum, at any address;
a unit answering zeros shows none) gets the same name ("polled like unit 2").
Confidence = 1 - 2^(-score/2).  If the named model is ruled out later, the
guess is withdrawn.  A user's device map always wins; the registry annotates
a guess that contradicts it.  After SETTLED answers a unit's verdict stands
(keeps the hot path cheap).
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, field
from typing import NamedTuple

from sniffer.frame import RESPONSE, Frame
from sniffer.protocols import PROTOCOLS

SCORE = 4
SETTLED = 200  # answers after which a unit's verdict stands (keeps the hot path cheap)
COMMON_END = 0x0100  # 0000H-00FFH: addresses nearly any device answers, never evidence of a model
STANDARD_EXCEPTIONS = frozenset(range(0x01, 0x0C))  # Modbus application protocol, section 7
GATEWAY_EXCEPTIONS = frozenset({0x0A, 0x0B})  # a gateway's answer, not the device's
W_VENDOR, W_DESCRIBED, W_RANGE, W_BARE, W_FITS, W_MISFIT = 3, 2, 1, 1, 1, -2
MAX_RANGE = 2  # values inside tight ranges: this much in all
MAX_BARE = 1  # registers only a model's map has, answered without a telling value: this much in all
NARROW = 256  # a min..max of at most this many steps is a rule a random register breaks
MAX_SIGNATURES = 64  # answered requests remembered per unit (for "polled like")
_REG_FUNCTIONS = {0x03: "read", 0x04: "read", 0x06: "write", 0x10: "write"}
_MODBUS = frozenset(name for name, p in PROTOCOLS.items() if p.family == "modbus")


class Verdict(NamedTuple):
    """A change of a unit's guess: model None = an earlier guess withdrawn."""

    model: str | None
    confidence: float
    evidence: str


def canonical(x):
    """Dicts and sets as tuples sorted by repr, recursively: equal content, equal value."""
    if isinstance(x, dict):
        return tuple(sorted(((canonical(k), canonical(v)) for k, v in x.items()), key=repr))
    if isinstance(x, (set, frozenset)):
        return tuple(sorted((canonical(v) for v in x), key=repr))
    if isinstance(x, (list, tuple)):
        return tuple(canonical(v) for v in x)
    return x


def confidence_of(score: float) -> float:
    return round(min(0.99, 1 - 2 ** (-score / 2)), 2)


def _narrow(r) -> bool:
    """A row whose value a device of another kind would likely break: an enum, a status word, a tight range."""
    return bool(r.enum or r.bits or (r.min is not None and r.max is not None and r.max - r.min <= NARROW))


def _unused_mask(regmap, bits_name: str) -> int:
    """Bits the manual calls unused or reserved in a bit-field table: a set one rules the model out."""
    mask = 0
    for fdef in regmap.bits.get(bits_name, []):
        name = str(fdef.get("name", "")).lower()
        if "unused" in name or name.strip("() ") == "reserved":
            for b in range(fdef["lo"], fdef["hi"] + 1):
                mask |= 1 << b
    return mask


def _rule(r) -> str:
    return "enum" if r.enum else "status bits" if r.bits else f"range {r.min}..{r.max}"


class Seen:
    """What `Identifier.observe` reads of a frame (and of its request), kept to observe it again elsewhere: a
    part of a capture decoded ahead is checked by observing its frames again from the true state."""

    __slots__ = ("role", "crc_ok", "unit", "protocol", "adu", "function", "raw", "peer", "annotations")

    def __init__(self, f, peer: bool = True) -> None:
        self.role, self.crc_ok, self.unit, self.protocol = f.role, f.crc_ok, f.unit, f.protocol
        self.adu, self.function, self.raw = f.adu, f.function, f.raw
        self.peer = Seen(f.peer, False) if peer and f.peer is not None else None
        self.annotations: list = []


class ModelFacts:
    """What one candidate's map says a device of that model can and cannot do."""

    def __init__(self, mid: str, regmap) -> None:
        self.id = mid
        self.map = regmap
        info = regmap.model
        fcs = info.function_codes
        self.functions = frozenset(fcs) | frozenset(info.vendor_function_codes) if fcs else None
        self.max_regs = info.max_registers_per_request
        self.max_frame = info.max_frame_bytes
        self.units = info.units
        self.exceptions = frozenset(regmap.exceptions)
        self._masks: dict[str, int] = {}

    def misfit(self, r, raw: int) -> str | None:
        """Why a register's value cannot come from this model, or None."""
        if r.enum:
            table = self.map.enums.get(r.enum)
            if table and raw not in table:
                return f"{r.addr:04X}H = {raw} is not in its table"
        if r.bits:
            mask = self._masks.get(r.bits)
            if mask is None:
                mask = self._masks[r.bits] = _unused_mask(self.map, r.bits)
            if raw & mask:
                return f"{r.addr:04X}H = {raw:04X}H sets bits the manual calls unused"
        if r.min is not None or r.max is not None:
            v = raw - 0x10000 if r.type == "s16" and raw >= 0x8000 else raw
            if (r.min is not None and v < r.min) or (r.max is not None and v > r.max):
                return f"{r.addr:04X}H = {v} outside {r.min}..{r.max}"
        return None


class RangeVerdict(NamedTuple):
    """One register range against one model (cached: polls repeat)."""

    missing: int | None  # first address the map does not have
    weight: int  # W_BARE if a register only this model has is in the range, else 0
    checked: tuple  # (offset, Register) of rows whose values can rule the model out
    telling: tuple  # (offset, Register) of those rows only this model has, with a narrow rule
    read_only: int | None  # first register the map calls read-only (an echoed write to it rules out)


@dataclass
class UnitEvidence:
    seen: int = 0
    items: dict[str, dict[tuple, tuple[int, str]]] = field(default_factory=dict)  # model -> key -> (weight, label)
    ruled_out: dict[str, str] = field(default_factory=dict)  # model -> first reason
    answered: set[tuple[int, int, int]] = field(default_factory=set)  # (function, address, count)
    guess: str | None = None
    confidence: float = 0.0
    via: int | None = None  # the unit whose name this one took ("polled like")
    dirty: bool = False
    siblings_seen: int = -1


class Identifier:
    def __init__(self, maps: dict) -> None:
        """maps: {model id: RegisterMap} of the candidate models (variants sharing a map count once)."""
        self.facts = [ModelFacts(mid, m) for mid, m in maps.items()]
        self.units: dict[int, UnitEvidence] = {}
        self.direct: dict[int, str] = {}  # unit -> model named from its own evidence
        self._direct_version = 0
        self._owners: dict[int, frozenset[str]] = {}
        self._ranges: dict[tuple[int, int], tuple[RangeVerdict, ...]] = {}
        vendor: dict[int, list[str]] = {}
        for mf in self.facts:
            for code in mf.exceptions - STANDARD_EXCEPTIONS:
                vendor.setdefault(code, []).append(mf.id)
        self._vendor_owner = {code: ids[0] for code, ids in vendor.items() if len(ids) == 1}

    # ---- what the maps say -------------------------------------------------
    def owners(self, addr: int) -> frozenset[str]:
        """The candidates whose map holds a (not reserved) register at addr."""
        o = self._owners.get(addr)
        if o is None:
            o = self._owners[addr] = frozenset(
                mf.id for mf in self.facts
                if (r := mf.map.registers.get(addr)) is not None and r.access != "reserved")
        return o

    def range_verdicts(self, a: int, q: int) -> tuple[RangeVerdict, ...]:
        key = (a, q)
        hit = self._ranges.get(key)
        if hit is not None:
            return hit
        if len(self._ranges) > 65536:
            self._ranges.clear()
        out = []
        for mf in self.facts:
            regs = mf.map.registers
            missing, weight, checked, telling, read_only = None, 0, [], [], None
            for k in range(q):
                r = regs.get(a + k)
                if r is None:
                    missing = a + k
                    break
                if r.access == "reserved":
                    continue
                if r.access == "R" and read_only is None:
                    read_only = a + k
                if r.enum or r.bits or r.min is not None or r.max is not None:
                    checked.append((k, r))
                if a + k >= COMMON_END and self.owners(a + k) == {mf.id}:
                    weight = W_BARE
                    if _narrow(r):
                        telling.append((k, r))
            out.append(RangeVerdict(missing, 0 if missing is not None else weight, tuple(checked), tuple(telling),
                                    read_only))
        hit = self._ranges[key] = tuple(out)
        return hit

    # ---- frames ---------------------------------------------------------------
    def settled(self, unit: int) -> bool:
        """True once a unit's verdict stands: observe() will not change it any more."""
        ev = self.units.get(unit)
        return ev is not None and ev.seen >= SETTLED

    def seed(self, unit: int, model: str, confidence: float) -> None:
        """Start a unit named `model` (carried over from the part of the capture before this one): the
        traffic here may still withdraw it, or name it otherwise on evidence of its own."""
        ev = self.units.get(unit)
        if ev is None:
            ev = self.units[unit] = UnitEvidence()
            self._check_unit(ev, unit)
        if model in ev.ruled_out:
            return
        ev.guess, ev.confidence, ev.via = model, confidence, None
        if self.direct.get(unit) != model:
            self.direct[unit] = model
            self._direct_version += 1

    # ---- a part of a capture decoded ahead of the parts before it (sniffer.parallel) --------------
    def snapshot(self) -> dict:
        """What the frames so far taught, as plain data: `restore` starts another identifier there."""
        return {"units": copy.deepcopy(self.units), "direct": dict(self.direct),
                "direct_version": self._direct_version}

    def restore(self, snap: dict) -> None:
        self.units = copy.deepcopy(snap["units"])
        self.direct = dict(snap["direct"])
        self._direct_version = snap["direct_version"]

    @staticmethod
    def fingerprint(snap: dict) -> tuple:
        """`snapshot()` in a canonical form: two identifiers with equal fingerprints name every unit the same
        way from here on, whatever they are shown (the caches of what the maps say aside)."""
        units = tuple((u, canonical(asdict(ev))) for u, ev in sorted(snap["units"].items()))
        return units, tuple(sorted(snap["direct"].items())), snap["direct_version"]

    def ruled_out(self, unit: int, model: str) -> str | None:
        ev = self.units.get(unit)
        return ev.ruled_out.get(model) if ev else None

    def observe(self, f: Frame) -> Verdict | None:
        """Feed one frame (answers carry the evidence); a Verdict when the unit's guess changes."""
        if f.role != RESPONSE or not f.crc_ok or f.unit in (None, 0) or f.protocol not in _MODBUS:
            return None
        adu = f.adu
        if len(adu) < 3:
            return None
        ev = self.units.get(f.unit)
        if ev is None:
            ev = self.units[f.unit] = UnitEvidence()
            self._check_unit(ev, f.unit)
        elif ev.seen >= SETTLED:
            return None
        ev.seen += 1
        if f.function & 0x80:
            self._exception(ev, adu[2])
        else:
            req = f.peer
            if req is None or not req.crc_ok or req.function != f.function:
                return None
            self._answer(ev, req, f)
        if not ev.dirty and ev.siblings_seen == self._direct_version:
            return None
        ev.dirty = False
        ev.siblings_seen = self._direct_version
        return self._decide(f.unit, ev)

    def _item(self, ev: UnitEvidence, model: str, key: tuple, weight: int, label: str) -> None:
        items = ev.items.setdefault(model, {})
        if key not in items:
            items[key] = (weight, label)
            ev.dirty = True

    def _rule_out(self, ev: UnitEvidence, model: str, reason: str) -> None:
        if model not in ev.ruled_out:
            ev.ruled_out[model] = reason
            ev.dirty = True

    def _check_unit(self, ev: UnitEvidence, unit: int) -> None:
        for mf in self.facts:
            if mf.units and not mf.units[0] <= unit <= mf.units[1]:
                self._rule_out(ev, mf.id, f"unit {unit} is outside its addresses {mf.units[0]}-{mf.units[1]}")

    def _exception(self, ev: UnitEvidence, code: int) -> None:
        owner = self._vendor_owner.get(code)
        if owner is not None:
            self._item(ev, owner, ("exc", code), W_VENDOR, f"exception {code:02X}H only {owner} defines")
        if code in GATEWAY_EXCEPTIONS:
            return
        for mf in self.facts:
            if mf.exceptions and code not in mf.exceptions:
                self._rule_out(ev, mf.id, f"answered exception {code:02X}H, which {mf.id} does not define")

    def _answer(self, ev: UnitEvidence, req: Frame, rsp: Frame) -> None:
        """Weigh one normal answer (with the request it answers) as evidence about each candidate model.

        First what any answer says: a function code or a frame length the model cannot produce rules it
        out.  Then, for a register read or write (03H/04H/06H/10H) whose address range is sane, the
        request's signature (function, address, count) is kept for "polled like", and each candidate
        still in the running is checked against its map's verdict on the range (`range_verdicts`,
        cached per range): an address its map lacks, more registers than its manual allows, or an
        echoed write to a read-only register rules it out.  A write stops there: any device echoes a
        write, so it is evidence against a model, never for it.  A read adds "fits" (its map holds the
        range), a "reg" item when only its map has these addresses, a misfit (-2) per value its map
        rules out, a "shape" marker per non-zero enum or status value, and a "value" item per telling
        register (only this map has it, a narrow rule) whose non-zero value fits.  Items are keyed, so
        the same register read a thousand times counts once; `score` caps what bare reads and ranges
        may add.  An answer whose data does not hold the registers the request names is no evidence.
        """
        fc = rsp.function
        for mf in self.facts:
            if mf.functions is not None and fc not in mf.functions:
                self._rule_out(ev, mf.id, f"answered function {fc:02X}H, which {mf.id} does not implement")
            # max_frame_bytes counts the frame on the wire: in ASCII its characters (the A510 manual:
            # 80 bytes "limits ASCII to far fewer than 32 registers")
            elif mf.max_frame and max(len(rsp.raw), len(req.raw)) > mf.max_frame:
                self._rule_out(ev, mf.id, f"answered a {max(len(rsp.raw), len(req.raw))}-byte frame "
                                          f"({mf.id}: at most {mf.max_frame})")
        kind = _REG_FUNCTIONS.get(fc)
        if kind is None or len(req.adu) < 6:
            return
        r_adu, adu = req.adu, rsp.adu
        a = (r_adu[2] << 8) | r_adu[3]
        if fc == 0x06:
            q, data = 1, adu[4:6]
        else:
            q = (r_adu[4] << 8) | r_adu[5]
            data = adu[3:3 + 2 * q] if kind == "read" else r_adu[7:7 + 2 * q]
        if not 1 <= q <= 125 or a + q > 0x10000 or len(data) != 2 * q:
            return
        if len(ev.answered) < MAX_SIGNATURES:
            if (fc, a, q) not in ev.answered:
                ev.answered.add((fc, a, q))
                ev.dirty = True
        label = f"{a:04X}H" + (f"-{a + q - 1:04X}H" if q > 1 else "")
        for mf, rv in zip(self.facts, self.range_verdicts(a, q)):
            if mf.id in ev.ruled_out:
                continue
            if rv.missing is not None:
                self._rule_out(ev, mf.id, f"answered {rv.missing:04X}H, which {mf.id}'s map does not have")
                continue
            if mf.max_regs and q > mf.max_regs and fc != 0x06:
                self._rule_out(ev, mf.id, f"answered {q} registers at once ({mf.id}: at most {mf.max_regs})")
                continue
            if kind == "write":  # any device echoes a write: evidence against a model only
                if rv.read_only is not None:
                    self._rule_out(ev, mf.id, f"echoed a write to {rv.read_only:04X}H, which {mf.id}'s map calls "
                                              f"read-only")
                continue
            self._item(ev, mf.id, ("fits",), W_FITS, "answers what its map holds")
            if rv.weight:
                self._item(ev, mf.id, ("reg", W_BARE, fc, a, q), W_BARE, f"read {label} (only its map has it)")
            misfit = set()
            for k, r in rv.checked:
                raw = (data[2 * k] << 8) | data[2 * k + 1]
                why = mf.misfit(r, raw)
                if why:
                    misfit.add(k)
                    self._item(ev, mf.id, ("misfit", r.addr), W_MISFIT, why)
                elif raw and (r.enum or r.bits):  # not evidence of its own (any address), but what a
                    self._item(ev, mf.id, ("shape", r.addr), 0, "")  # "polled like" unit must also show
            for k, r in rv.telling:
                raw = (data[2 * k] << 8) | data[2 * k + 1]
                if k not in misfit and raw:
                    w = W_DESCRIBED if r.enum or r.bits else W_RANGE
                    self._item(ev, mf.id, ("value", r.addr, w), w,
                               f"{r.id or r.name} ({r.addr:04X}H) = {raw:#06x} fits its {_rule(r)}")

    # ---- the verdict -------------------------------------------------------------
    @staticmethod
    def score(items: dict) -> int:
        bare = sum(w for key, (w, _) in items.items() if key[0] == "reg")
        ranged = sum(w for key, (w, _) in items.items() if key[0] == "value" and key[2] == W_RANGE)
        vendor = any(key[0] == "exc" for key in items)
        rest = sum(w for key, (w, _) in items.items()
                   if key[0] not in ("reg", "fits", "value") or (key[0] == "fits" and vendor)
                   or (key[0] == "value" and key[2] != W_RANGE))
        return rest + min(bare, MAX_BARE) + min(ranged, MAX_RANGE)

    @staticmethod
    def _own(items: dict) -> bool:
        """Evidence only this model gives (not just 'its map fits')."""
        return any(key[0] in ("exc", "reg", "value") for key in items)

    def _decide(self, unit: int, ev: UnitEvidence) -> Verdict | None:
        if ev.guess is not None and ev.guess in ev.ruled_out:
            was, ev.guess, ev.via, ev.confidence = ev.guess, None, None, 0.0
            if self.direct.pop(unit, None) is not None:
                self._direct_version += 1
            return Verdict(None, 0.0, f"not {was}: {ev.ruled_out[was]}")
        alive = {m: items for m, items in ev.items.items() if m not in ev.ruled_out}
        scores = {m: self.score(items) for m, items in alive.items()}
        best = max(scores, key=lambda m: (scores[m], m), default=None)
        if (best is not None and scores[best] >= SCORE and self._own(alive[best])
                and not any(self._own(items) for m, items in alive.items() if m != best)):
            conf = confidence_of(scores[best])
            changed = best != ev.guess
            ev.guess, ev.confidence, ev.via = best, conf, None
            if self.direct.get(unit) != best:
                self.direct[unit] = best
                self._direct_version += 1
            return Verdict(best, conf, self._explain(ev, best, scores[best])) if changed else None
        if ev.guess is None and not any(self._own(items) for items in alive.values()):
            return self._polled_like(unit, ev)
        return None

    def _polled_like(self, unit: int, ev: UnitEvidence) -> Verdict | None:
        """No evidence of its own: the name of a unit polled the same way, if nothing rules it out."""
        for other, model in sorted(self.direct.items()):
            mine = ev.items.get(model, ())
            if (other == unit or model in ev.ruled_out or any(k[0] == "misfit" for k in mine)
                    or not any(k[0] == "shape" for k in mine)):  # zeros fit every table: no shape of the model
                continue
            shared = ev.answered & self.units[other].answered
            if len(shared) >= 2 and 2 * len(shared) >= len(ev.answered):
                conf = round(self.units[other].confidence * len(shared) / len(ev.answered) * 0.9, 2)
                ev.guess, ev.confidence, ev.via = model, conf, other
                same = ", ".join(f"{fc:02X}H {a:04X}H" + (f"-{a + q - 1:04X}H" if q > 1 else "")
                                 for fc, a, q in sorted(shared)[:4])
                return Verdict(model, conf, f"confidence {conf}: polled like unit {other} ({model}), "
                                            f"{len(shared)} of its {len(ev.answered)} answered requests the same "
                                            f"({same}){self._ruled_text(ev, model)}")
        return None

    def _explain(self, ev: UnitEvidence, model: str, score: int) -> str:
        items = sorted((kv for kv in ev.items[model].items() if kv[0][0] != "shape"), key=lambda kv: -kv[1][0])
        shown = [f"{label} ({w:+d})" for _, (w, label) in items[:5]]
        more = f", +{len(items) - 5} more" if len(items) > 5 else ""
        return (f"score {score}, confidence {confidence_of(score)}: {'; '.join(shown)}{more}"
                f"{self._ruled_text(ev, model)}")

    @staticmethod
    def _ruled_text(ev: UnitEvidence, model: str) -> str:
        others = [f"not {m}: {why}" for m, why in sorted(ev.ruled_out.items()) if m != model]
        return f"; {'; '.join(others[:3])}" if others else ""
