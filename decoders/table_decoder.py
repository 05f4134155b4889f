"""A drive model from its register map: names, ids, scales, units, enums, bits, write checks.

`TableDecoder` is the one generic interpreter of register-map rows; a model
package adds only what a table cannot say (subclass hooks `check_request`,
`value_of`).  Values scaled through another register (TDS-V8 frequency =
raw / 30000 * Cn-02) use the per-unit register shadow: until the reference
register is known (seen on the bus, given in the bus file, or carried over from
the part of the capture before: decoders/carry.py) the value is *provisional*:
in % of that register, under a name of its own ("Output frequency (% of Cn-02)",
`provisional: true`), so no view compares it with the Hz values that share the
register (docs/values.md).

A value of several registers (u32, s32, f32, u64, s64, f64, str; decoders/regtypes.py) is one point
when a frame carries all its registers: named by its row, at its first address, its span over all
its bytes, `raw` its registers joined, `words` the registers as they are on the wire (what the
register shadow holds).  A frame that carries only some of them (a read or write that starts or ends
inside the value) gets each of those registers as a point of its own, shown raw, with `part`
[word index, words] and a `model.register.split` annotation.
"""

from __future__ import annotations

import math

from sniffer.codes import ALARM_CAT, ERROR, FAULT_CAT, INFO, WARNING, Code, note
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.protocols import MODBUS_TABLES, modbus_range_ok

from . import regtypes
from .base import UnitState
from .generic.decoder import GenericModbus
from .generic.names import EXCEPTION_NAMES
from .tables import Register, RegisterMap

# The codes a model described by its register map may emit beyond generic Modbus: what a manual's map lets
# the decoder check.  Declared here, beside the decoder that emits them; the code book is assembled from
# each decoder class's `codes` (sniffer.codes.CodeBook).
READ_ONLY = Code("model.write.read_only", ERROR, "write to a read-only register")
RESERVED = Code("model.write.reserved", ERROR, "write to a reserved register")
UNKNOWN_REG = Code("model.register.unknown", WARNING, "register not in the model's register map")
RANGE = Code("model.value.range", WARNING, "written value outside the manual's range")
BROADCAST_REG = Code("model.broadcast.register", ERROR, "broadcast write to a register the manual does not allow")
TOO_MANY = Code("model.request.too_many", ERROR, "more registers in one request than the manual allows")
SCALE_PENDING = Code(
    "model.scale.pending", INFO,
    "scaled through a register not known yet: a provisional value, in %, under a name of its own"
)
VENDOR_EXCEPTION = Code("model.exception.vendor", WARNING, "vendor exception code")
SPLIT = Code("model.register.split", WARNING, "a read or write covers only some registers of a multi-register value")
FRAME_LONG = Code("model.frame.too_long", WARNING, "frame longer than the manual's maximum frame length")
FAULT = Code("model.fault", ERROR, "the drive reports a fault (trip): its fault code or fault bits", FAULT_CAT)
ALARM = Code("model.alarm", WARNING, "the drive reports an alarm (warning): its alarm code or alarm bits", ALARM_CAT)
FUNCTION = Code("model.function.unsupported", WARNING, "function code the manual does not list for this model")
SUBFUNCTION = Code(
    "model.diagnostics.subfunction", WARNING, "diagnostics (08H) sub-function the manual does not allow"
)
NOT_AVAILABLE = Code(
    "model.value.not_available", WARNING, "register holds a marker value, not a measurement: shown as not available"
)
MODEL_CODES = (READ_ONLY, RESERVED, UNKNOWN_REG, RANGE, BROADCAST_REG, TOO_MANY, SCALE_PENDING, VENDOR_EXCEPTION,
               SPLIT, FRAME_LONG, SUBFUNCTION, NOT_AVAILABLE, FUNCTION, FAULT, ALARM)
_REGISTERS = ("holding", "input")

_DIGITS = {1.0: 0, 0.1: 1, 0.01: 2, 0.001: 3}


class TableDecoder(GenericModbus):
    # declared on the class (a model package adds its own: `codes = TableDecoder.codes + (...)`), so the code
    # book is assembled without loading a map
    codes: tuple[Code, ...] = GenericModbus.codes + MODEL_CODES

    def __init__(self, regmap: RegisterMap) -> None:
        self.map = regmap  # also the holding view: `registers` holds the holding and table-less rows
        self._imap = regmap.view("input")  # the input registers' rows (the same map unless a row says table)
        self.model = regmap.model_id
        info = regmap.model
        self.max_regs = info.max_registers_per_request
        bc = info.broadcast_registers
        self.broadcast_regs = set(bc) if bc is not None else None
        self.complete_exceptions = info.exception_table == "complete"
        self.max_frame = info.max_frame_bytes
        subs = info.loopback_subfunctions
        self.loop_subfunctions = set(subs) if subs is not None else None
        fcs = info.function_codes  # the manual's list: another code is answered 01H
        self.functions = frozenset(fcs) | frozenset(info.vendor_function_codes) if fcs else None
        # the exception the manual says answers an unknown function (SPL: 51H FUNCTION CODE ERROR), else 01H
        self.function_exception = next(
            (c for c, e in sorted(regmap.exceptions.items())
             if "function" in f"{e.get('name', '')} {e.get('text', '')}".lower()), 0x01)
        # registers whose non-zero value is a trip (fault) or a warning (alarm): model.fault / model.alarm
        self.trips = {**{a: (ALARM, "alarm") for a in info.alarm_registers},
                      **{a: (FAULT, "fault") for a in info.fault_registers}}
        # (address, raw) -> the marker's meaning: a raw value that is no measurement
        self.markers = {(m.addr, m.raw): m for m in info.not_available}
        # the holding registers other rows are scaled through (TDS-V8 Cn-02): carried over (carried())
        self.scale_refs = tuple(sorted({r.scale_by["addr"] for m in (regmap, self._imap)
                                        for r in m.registers.values() if r.scale_by}))

    # ---- what a part of a capture carries over (decoders/carry.py) ----------------------
    carried_extra: tuple[str, ...] = ()  # the UnitState.extra keys a model carries over (settings it saw)

    def carried(self, state: UnitState) -> dict:
        """What a unit's next part starts with: its scaling registers' raw values, its carried settings."""
        out = {}
        held = {str(a): state.holding[a] for a in self.scale_refs if a in state.holding}
        if held:
            out["holding"] = held
        extra = {k: state.extra[k] for k in self.carried_extra if state.extra.get(k) is not None}
        if extra:
            out["extra"] = extra
        return out

    def preset(self, state: UnitState, params: dict) -> None:
        """Parameters a bus file states for the unit (`{"Cn-02": 60}`: the manual's id, the value in the
        register's unit, or "60 Hz") into its shadow, as if read on the bus; ValueError (one line) for an
        id the map does not have or a value that does not fit."""
        from .carry import param_raw

        for pid, value in params.items():
            r = self.map.by_id.get(pid) or next((x for k, x in self.map.by_id.items() if k.lower() == pid.lower()),
                                                None)
            if r is None or r.table == "input" or r.words != 1:
                what = "has no holding register" if r is not None else "has no parameter"
                raise ValueError(f"{self.model} {what} {pid!r}")
            state.holding[r.addr] = param_raw(r, value, self.model)
            state.version += 1

    # ---- values ------------------------------------------------------------
    def value_of(self, r: Register, raw: int, state: UnitState):
        """(value, unit, pending) of one register's raw value (its registers joined: regtypes.join)."""
        raw = r.number(raw)
        sb = r.scale_by
        if sb:
            ref = self.map.registers.get(sb["addr"])
            ref_raw = state.holding.get(sb["addr"])
            if ref is None or ref_raw is None or ref.words != 1:
                return round(raw * 100.0 / sb["full"], 2), "%", True
            ref_val, ref_unit, _ = self.value_of(ref, ref_raw, state)
            return round(raw * ref_val / sb["full"], 2), ref_unit or r.unit, False
        scale = r.scale
        if scale == 1:
            return raw, r.unit or None, False
        if type(raw) is float:  # scaled to the float's own precision, not to the scale's digits
            return float(f"{raw * scale:{'.7g' if r.type == 'f32' else '.15g'}}"), r.unit or None, False
        return round(raw * scale, _DIGITS.get(scale, 4)), r.unit or None, False

    def range_text(self, space: str, a: int, q: int) -> str:
        """Registers named as the manual names them: parameter ids where both ends have one
        (`An-01..An-02 (2)`), else hex addresses (`2520H..252FH (16)`); coils stay numbers."""
        if space not in ("holding", "input"):
            return super().range_text(space, a, q)
        where = "" if space == "holding" else "input "
        last = a + q - 1
        if q < 1:
            return f"{where}{a:04X}H ({q})"
        regs = self.view(space).registers
        r0, r1 = regs.get(a), regs.get(last)
        if r0 is not None and r1 is not None and r0.id and r1.id:
            return f"{where}{r0.id if r0 is r1 else r0.id + '..' + r1.id} ({q})"
        return f"{where}{a:04X}H ({q})" if q == 1 else f"{where}{a:04X}H..{last:04X}H ({q})"

    def view(self, space: str | None) -> RegisterMap:
        """The rows a read or write of `space` sees (tables.RegisterMap.view)."""
        return self._imap if space == "input" else self.map

    def point(self, space: str, address: int | None, raw: int, state: UnitState) -> dict:
        m = self._imap if space == "input" else self.map
        r = m.registers.get(address) if space in _REGISTERS and address is not None else None
        if r is None or r.words != 1 or r.byte_order != "big":
            hit = m.parts.get(address) if space in _REGISTERS and address is not None else None
            if hit is not None:  # one register of a value of several: shown raw
                return self.part_point(hit[0], hit[1], raw)
            if r is None:
                pt = super().point(space, address, raw, state)
                if address is not None and space in _REGISTERS:
                    pt["name"] = f"{space}[{address:04X}H]"  # an unmapped register, in the manual's notation
                return pt
            return self.value_point(r, [raw], state)  # a u16 / s16 with its bytes swapped
        return self._named(r, address, raw, state)

    def value_point(self, r: Register, words: list[int], state: UnitState) -> dict:
        """The point of a row's value from all its registers (in address order, as on the wire)."""
        if r.type == regtypes.TEXT:
            raw, text = regtypes.text(words, r.byte_order)
            return {"name": r.name, "address": r.addr, "raw": raw, "value": text, "unit": r.unit or None,
                    "id": r.id, "words": words}
        pt = self._named(r, r.addr, regtypes.join(words, r.word_order, r.byte_order), state)
        pt["words"] = words
        return pt

    def _named(self, r: Register, address: int, raw: int, state: UnitState) -> dict:
        marker = self.markers.get((address, raw)) if self.markers else None
        if marker is not None:
            return {"name": r.name, "address": address, "raw": raw, "value": None, "unit": None, "id": r.id,
                    "text": f"not available ({raw:04X}H)", "not_available": marker.text}
        value, unit, pending = self.value_of(r, raw, state)
        pt = {"name": self.provisional_name(r) if pending else r.name, "address": address, "raw": raw,
              "value": value, "unit": unit, "id": r.id}
        if r.enum:
            text = self.map.enum_text(r.enum, raw)
            pt["text"] = text if text is not None else f"unknown code {raw}"
        elif r.bits:
            pt["text"] = self.map.bits_text(r.bits, raw)
        elif type(value) is float and not math.isfinite(value):
            pt["text"] = str(value)  # JSON writes NaN and infinity as null: the text keeps them
        if pending:
            pt["provisional"] = True
        return pt

    def provisional_name(self, r: Register) -> str:
        """The name of a row's value while the register it is scaled through is not known: what it is
        then ("Output frequency (% of Cn-02)"), never the name of its scaled value."""
        ref = self.map.registers.get(r.scale_by["addr"]) if r.scale_by else None
        return f"{r.name} (% of {ref.id or ref.name if ref is not None else 'its reference'})"

    @staticmethod
    def part_point(r: Register, k: int, raw: int) -> dict:
        """Register k of row r's value, without the others: its own raw number."""
        return {"name": f"{r.name} [word {k + 1}/{r.words}]", "address": r.addr + k, "raw": raw, "value": raw,
                "unit": None, "id": r.id, "part": [k, r.words]}

    def make_points(self, space: str, addr: int | None, values: list[int], state: UnitState,
                    offset: int) -> list[dict]:
        """Points of consecutive registers: a value of several registers joined where all are here."""
        m = self._imap if space == "input" else self.map
        if addr is None or space not in _REGISTERS or not m.any_part(addr, len(values)):
            return super().make_points(space, addr, values, state, offset)
        parts = m.parts
        out = []
        n, i = len(values), 0
        while i < n:
            a = addr + i
            hit = parts.get(a)
            w = 1
            if hit is None:
                pt = self.point(space, a, values[i], state)
            else:
                r, k = hit
                if k == 0 and i + r.words <= n:
                    w = r.words
                    pt = self.value_point(r, values[i:i + w], state)
                else:
                    pt = self.part_point(r, k, values[i])
            pt["span"] = [offset + 2 * i, offset + 2 * (i + w)]
            out.append(pt)
            i += w
        return out

    # ---- frames --------------------------------------------------------------
    def decode(self, f: Frame, request: Frame | None, state: UnitState) -> None:
        refs = self.scale_refs
        if refs:
            held = state.holding
            before = [held.get(a) for a in refs]
            super().decode(f, request, state)
            if f.writes and before != [held.get(a) for a in refs]:
                state.version += 1  # a register that scales others changed: carried over from here on
        else:
            super().decode(f, request, state)
        if f.role == REQUEST and f.crc_ok:
            self.check_request(f, state)
        if self.map.parts or self._imap.parts:
            self._split(f)
        if self.max_frame and len(f.raw) > self.max_frame:
            f.annotations.append(note(FRAME_LONG, f"{len(f.raw)} bytes on the wire (manual: at most {self.max_frame};"
                                      " an ASCII frame counted in characters, ':' to LF)", 0, len(f.raw)))
        if self.trips and f.role == RESPONSE and f.crc_ok and f.function in (0x03, 0x04):
            self._trips(f)
        if self.markers:
            for p in f.points:
                if "not_available" in p:
                    f.annotations.append(note(NOT_AVAILABLE, f"{p['name']} raw {p['raw']:04X}H: {p['not_available']}",
                                              *p["span"]))
        if any(p.get("provisional") for p in f.points):
            ref = next(p for p in f.points if p.get("provisional"))
            r = self.view(MODBUS_TABLES.get(f.function)).registers[ref["address"]]
            ref_reg = self.map.registers.get(r.scale_by["addr"])
            who = f"{ref_reg.id or ref_reg.name} (0x{ref_reg.addr:04X})" if ref_reg else "the reference register"
            f.annotations.append(note(SCALE_PENDING,
                                      f"{who} not known yet: {r.name} shown as {ref['name']!r}, in % "
                                      "(read it on the bus, or give it in the bus file's [parameters])",
                                      0, len(f.raw)))

    def _trips(self, f: Frame) -> None:
        """A read answer whose fault / alarm register is not 0: the drive tripped or warns (the text as
        the manual gives it: "OL1 — Motor overload")."""
        trips = self.trips
        for p in f.points:
            hit = trips.get(p.get("address"))
            if hit is not None and p.get("raw"):
                code, what = hit
                f.annotations.append(note(code, f"{what}: {p.get('text') or p['raw']} ({p['name']})",
                                          *p.get("span", (0, len(f.raw)))))

    def _split(self, f: Frame) -> None:
        """Annotate every point that is one register of a value the frame does not carry whole."""
        for p in f.points:
            part = p.get("part")
            if part is None:
                continue
            k, w = part
            r = self.view(MODBUS_TABLES.get(f.function)).registers[p["address"] - k]
            order = "" if r.type == regtypes.TEXT else f", {'high' if r.word_order == 'big' else 'low'} word first"
            f.annotations.append(note(SPLIT, f"0x{p['address']:04X} is register {k + 1} of {w} of "
                                             f"{r.id or r.name} ({r.type} at 0x{r.addr:04X}{order}): shown raw",
                                      *p["span"]))

    def _split_range(self, f: Frame, a: int, q: int, start: int) -> None:
        """Annotate a read of registers a..a+q-1 that starts or ends inside a value of several registers."""
        if not modbus_range_ok(f.function, a, q):
            return
        parts = self.view(MODBUS_TABLES.get(f.function)).parts
        first, last = parts.get(a), parts.get(a + q - 1)
        if first is not None and first[1] > 0:  # starts after the value's first register
            r = first[0]
        elif last is not None and last[1] < last[0].words - 1:  # ends before its last
            r = last[0]
        else:
            return
        f.annotations.append(note(SPLIT, f"read 0x{a:04X}..0x{a + q - 1:04X} cuts {r.id or r.name} "
                                         f"({r.type} at 0x{r.addr:04X}..0x{r.addr + r.words - 1:04X})",
                                  start, start + 4))
    def exception_info(self, code: int) -> tuple[str, str, str | None]:
        """The model's [exceptions] table is the source: its manual's name first, the standard meaning
        of a redefined code as a note.  With `[model] exception_table = "complete"` (the manual
        prints its whole table) the table is the list, and any other code is flagged; otherwise the
        table adds to the standard codes, and a code in neither is flagged."""
        table = self.map.exceptions
        std = EXCEPTION_NAMES.get(code)
        e = table.get(code)
        if e is None and not self.complete_exceptions:
            return super().exception_info(code)
        if e is None:
            name = std or "UNKNOWN EXCEPTION"
            also = "standard Modbus meaning shown" if std else "nor in the Modbus standard"
            why = f"{code:02X}H is not in the {self.model} manual's exception table ({also})"
            return name, f"{code:02X}H {name}", why
        name = e.get("name") or e.get("text") or f"exception {code:02X}H"
        detail = f"{code:02X}H {name}"
        text = e.get("text")
        if text and text.casefold() != name.casefold():
            detail += f": {text}"
        if e.get("section"):
            detail += f" [{e['section']}]"
        if std and std.casefold() != name.casefold():
            detail += f"; standard Modbus {code:02X}H: {std}"
        unlisted = f"{code:02X}H is not in the {self.model} manual's exception table" if e.get("unlisted") else None
        return name, detail, unlisted

    def _exception(self, f: Frame, fc: int, body: bytes) -> None:
        super()._exception(f, fc, body)
        code = body[0] if body else None
        if code is not None and code not in EXCEPTION_NAMES and code in self.map.exceptions:
            f.annotations.append(
                note(VENDOR_EXCEPTION, f"{code:02X}H is a {self.model} code, not a standard one", 2, 3))

    def check_request(self, f: Frame, state: UnitState) -> None:
        """Annotate what the manual forbids in a request (models extend it)."""
        fc = f.function
        raw = f.adu
        if self.functions is not None and fc not in self.functions:
            listed = ", ".join(f"{x:02X}H" for x in sorted(self.functions))
            f.annotations.append(note(FUNCTION, f"function {fc:02X}H: the {self.model} manual lists {listed} "
                                                f"(another code is answered with exception "
                                                f"{self.function_exception:02X}H)", 1, 2))
        if fc == 0x08 and self.loop_subfunctions is not None and len(raw) >= 4:
            sub = (raw[2] << 8) | raw[3]
            if sub not in self.loop_subfunctions:
                allowed = ", ".join(f"{x:04X}H" for x in sorted(self.loop_subfunctions))
                f.annotations.append(note(SUBFUNCTION, f"sub-function {sub:04X}H (the {self.model} manual allows only "
                                          f"{allowed}; the drive answers exception 01H)", 2, 4))
        if fc in (0x03, 0x04, 0x10, 0x17) and len(raw) >= 6 and self.max_regs:
            qty = (raw[4] << 8) | raw[5]
            if qty > self.max_regs:
                f.annotations.append(note(TOO_MANY, f"{qty} registers (manual: at most {self.max_regs})", 4, 6))
        if fc in (0x03, 0x04, 0x17) and len(raw) >= 6 and self.view(MODBUS_TABLES.get(fc)).parts:
            self._split_range(f, (raw[2] << 8) | raw[3], (raw[4] << 8) | raw[5], 2)
        if fc not in (0x06, 0x10):
            return
        for pt in f.points:
            a = pt["address"]
            span = pt["span"]
            r = self.map.registers.get(a)
            part = pt.get("part")
            if part is not None:
                r = self.map.registers.get(a - part[0])
            if r is None:
                f.annotations.append(note(UNKNOWN_REG, f"0x{a:04X} is not in the {self.model} map", *span))
                continue
            if r.access == "reserved":
                # A block write may pass over reserved registers with 0: the TDS-V8
                # manual's own example (section 9) writes 0000H-0007H that way.
                if not (fc == 0x10 and pt["raw"] == 0):
                    f.annotations.append(note(RESERVED, f"0x{a:04X} is reserved", *span))
            elif r.access == "R":
                f.annotations.append(note(READ_ONLY, f"0x{a:04X} {r.name} is read-only", *span))
            raw_v = r.number(pt["raw"]) if part is None and r.type != regtypes.TEXT else None
            if raw_v is not None and ((r.min is not None and raw_v < r.min) or (r.max is not None and raw_v > r.max)):
                f.annotations.append(
                    note(RANGE, f"{r.id or r.name} = {raw_v}, manual range {r.min}..{r.max}", *span)
                )
            if f.unit == 0 and self.broadcast_regs is not None and a not in self.broadcast_regs:
                allowed = ", ".join(f"0x{x:04X}" for x in sorted(self.broadcast_regs))
                f.annotations.append(note(BROADCAST_REG, f"broadcast to 0x{a:04X} (allowed: {allowed})", *span))


__all__ = ["TableDecoder", "MODEL_CODES", "RESPONSE"]
