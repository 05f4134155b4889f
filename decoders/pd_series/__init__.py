"""PD-series inverters (protocols pd-rtu / pd-ascii): model id "pd-series".

Decodes the six functions of shared/manuals/pd-series-protocol.txt (01H read
parameter, 02H write parameter, 03H control, 04H read status, 05H write
frequency, 08H loop test) and the error replies 81H/83H, from `frame.adu`
(ADDR FUNC LEN DATA, binary for both wire encodings).  Layouts and tables are
in `schema.py`; our reading of the manual's contradictions is in NOTES.md.

* DATA is decoded by the bytes present (lenient), not by LEN: the framer has
  already flagged a LEN that does not count them (`pd.len.mismatch`).
* A reply means something only through its request: a status reply without
  its CFG echo (the manual's own l.175 example) takes CFG from the request.
* Error replies carry no error-code byte: `exception` is {code: the wire
  function 81H/83H, name: the manual's wording}; 81H answers 01H *and* 02H
  (l.111, l.125), the framer gives it the pairing key 82H after a write.
* The pairer's Modbus request/response rules (byte counts of Modbus
  01H-04H) apply to Modbus protocols only; PD pairs get the PD check here.
* Never raises: bytes that do not fit become annotations.
"""

from __future__ import annotations

from sniffer import codes as core
from sniffer.codes import ERROR, EXCEPTION_CAT, INFO, WARNING, Code, note_in
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.protocols import PD_TABLES

from ..base import UnitState
from .schema import (
    BROADCAST_READS, CNST_BITS, CNTR_BITS, ERRORS, FUNCTIONS, MAX_DATA, PARAMS, STATUS, Param,
    bits_text, enum_text,
)

# The codes this decoder may emit, declared here (sigrok's decoders declare their annotations so): the
# code book (sniffer.codes.CodeBook) is assembled from `PdSeriesDecoder.codes`.  "l.N": the manual's line.
DATA_SHORT = Code("pd.data.short", ERROR, "DATA too short for the function")
DATA_EXTRA = Code("pd.data.extra", WARNING, "more DATA bytes than the function's layout: the rest shown raw")
DATA_LONG = Code("pd.data.long", WARNING, "more than 25 DATA bytes (l.183: fifty ASCII characters at most)")
UNIT_RANGE = Code("pd.unit.range", WARNING, "address outside 0-250 (l.71-73)")
BROADCAST_READ = Code("pd.broadcast.read", WARNING, "broadcast read: the manual says no inverter answers")
ERROR_REPLY = Code("pd.error.reply", WARNING, "error reply (81H/83H)", EXCEPTION_CAT)
STATUS_CFG = Code("pd.status.cfg", WARNING, "status selector CFG outside 0-7 (l.165)")
NO_REQUEST = Code("pd.decode.no_request", INFO, "reply decoded without its request")
PARAM_UNKNOWN = Code("pd.param.unknown", INFO, "parameter not described in the manual: raw value")
READ_ONLY = Code("pd.write.read_only", ERROR, "write to a parameter the manual says cannot be set")
RANGE = Code("pd.value.range", WARNING, "written value outside the manual's set range")
RUNNING = Code("pd.write.running", WARNING, "parameter without ** written while the inverter runs (l.335)")
LOOP_ECHO = Code("pd.loop.echo", WARNING, "loop test reply is not an echo of its request")
DECODER_CODES = (DATA_SHORT, DATA_EXTRA, DATA_LONG, UNIT_RANGE, BROADCAST_READ, ERROR_REPLY, STATUS_CFG,
                 NO_REQUEST, PARAM_UNKNOWN, READ_ONLY, RANGE, RUNNING, LOOP_ECHO)


def load() -> "PdSeriesDecoder":
    return PdSeriesDecoder()


class PdSeriesDecoder:
    model = "pd-series"
    codes: tuple[Code, ...] = DECODER_CODES + (core.PAIR_MISMATCH,)

    def tables(self) -> dict:
        """The protocol's tables (schema.py) as JSON rows, for a capture to carry (decoders.mapfile)."""
        import dataclasses

        def dataclass_rows(rows) -> list[dict]:
            return [dataclasses.asdict(r) for r in rows]

        return {
            "source": "decoders/pd_series/schema.py (the manual: pd-series-protocol.txt, 'line' = its line)",
            "parameters": [{"id": p.id, **row} for p, row in zip(PARAMS.values(), dataclass_rows(PARAMS.values()))],
            "status_selectors": dataclass_rows(STATUS.values()),
            "control_bits": dataclass_rows(CNTR_BITS),
            "status_bits": dataclass_rows(CNST_BITS),
            "functions": dataclass_rows(FUNCTIONS.values()),
            "error_replies": dataclass_rows(ERRORS.values()),
        }

    def decode(self, f: Frame, request: Frame | None, state: UnitState) -> None:
        adu = f.adu
        if len(adu) < 2:
            return
        fc = adu[1]  # the wire byte (f.function may be the pairing key 82H)
        data = adu[3:]
        role = f.role if f.role in (REQUEST, RESPONSE) else (RESPONSE if fc & 0x80 else REQUEST)
        if adu[0] > 250:
            self._note(f, UNIT_RANGE, f"address {adu[0]}", 0, 1)
        if len(data) > MAX_DATA:
            self._note(f, DATA_LONG, f"{len(data)} DATA bytes", 3 + MAX_DATA, 3 + len(data))
        if fc in ERRORS:
            self._error(f, fc, data, request, state)
        elif fc in FUNCTIONS:
            self._function(f, fc, role, data, request, state)
        else:
            f.summary = f"function {fc:02X}H ({len(data)} data bytes)"
        if f.unit == 0 and role == REQUEST and fc in BROADCAST_READS:
            self._note(f, BROADCAST_READ, f"{FUNCTIONS[fc].name} to address 0: {FUNCTIONS[fc].broadcast}", 0, 1)
        if role == RESPONSE:
            self._check_pair(f, fc, request)

    # ---------------------------------------------------------------- helpers
    def _note(self, f: Frame, code: Code, detail: str, start: int, end: int) -> None:
        """An annotation on ADU bytes [start, end) (the registry maps them onto ASCII characters)."""
        f.annotations.append(note_in(code, detail, start, end, len(f.adu)))

    def _function(self, f, fc, role, data, request, state) -> None:
        from construct import ConstructError  # imported once, on the first PD frame (layouts.py)

        from .layouts import layout_for

        name = FUNCTIONS[fc].name
        layout, k = layout_for(fc, role, len(data))
        parsed = None
        if layout is not None:
            try:
                parsed = layout.parse(data[:k])
            except (ConstructError, ValueError, IndexError):
                parsed = None
        if parsed is None:
            self._note(f, DATA_SHORT, f"{len(data)} DATA byte(s) too few for {name} {role}", 2, 3 + len(data))
            f.summary = f"{name} {role} (malformed)"
            return
        if k < len(data):
            self._note(f, DATA_EXTRA, f"{len(data) - k} byte(s) after the {name} {role} layout: "
                       f"{data[k:].hex()}", 3 + k, 3 + len(data))
        if fc in (0x01, 0x02):
            self._param(f, fc, role, parsed, state, k)
        elif fc == 0x03:
            self._control(f, role, parsed, state)
        elif fc == 0x04:
            self._status(f, role, parsed, request, state, k)
        elif fc == 0x05:
            pt = {"name": "frequency", "address": None, "raw": parsed.frequency,
                  "value": round(parsed.frequency * 0.01, 2), "unit": "Hz", "span": [3, 5] if k == 2 else [4, 6]}
            f.points = [pt]
            f.summary = f"{'write frequency' if role == REQUEST else 'frequency'} {pt['value']:.2f} Hz"
        else:
            f.summary = f"loop test {role}: {parsed.data.hex(' ') or '(no data)'}"
        if f.unit == 0 and role == REQUEST:
            f.summary += " (broadcast)"

    def _point(self, f: Frame, number: int, raw: int, span: list[int]) -> dict:
        par = PARAMS.get(number)
        if par is None:
            self._note(f, PARAM_UNKNOWN, f"PD{number:03d} is not described in the manual", 3, 4)
            return {"name": f"PD{number:03d}", "address": number, "raw": raw, "value": raw, "unit": None,
                    "id": f"PD{number:03d}", "span": span}
        value = raw if par.scale == 1 else round(raw * par.scale, 2)
        pt = {"name": f"{par.id} {par.name}", "address": number, "raw": raw, "value": value,
              "unit": par.unit, "id": par.id, "span": span}
        text = enum_text(par, raw)
        if text is not None:
            pt["text"] = text
        elif par.enum:
            pt["text"] = f"unknown code {raw}"
        return pt

    def _param(self, f, fc, role, p, state, k) -> None:
        number = p.param
        par = PARAMS.get(number)
        label = f"{par.id} {par.name}" if par else f"PD{number:03d}"
        if "value" not in p:
            if fc == 0x01 and role == REQUEST:
                f.summary = f"read {label}"
            else:
                self._note(f, DATA_SHORT, f"{label}: no value bytes", 3, 4)
                f.summary = f"{FUNCTIONS[fc].name} {role} {label} (no value)"
            return
        if fc == 0x01 and role == REQUEST:  # the value bytes of a read are placeholders
            f.summary = f"read {label}"
            return
        pt = self._point(f, number, p.value, [4, 3 + k])  # PARAM at 3, then a byte or a word
        f.points = [pt]
        verb = {(0x01, RESPONSE): "", (0x02, REQUEST): "write ", (0x02, RESPONSE): "wrote "}[(fc, role)]
        f.summary = verb + _pt_text(pt)
        if fc == 0x02 and role == REQUEST and f.crc_ok and par is not None:
            self._check_write(f, par, p.value, state)
        if f.crc_ok and (role == RESPONSE or f.unit == 0):  # a reply, or a broadcast nobody answers
            state.commit(f, PD_TABLES[fc], number, [p.value])

    def _check_write(self, f: Frame, par: Param, raw: int, state: UnitState) -> None:
        span = (4, len(f.adu))
        if par.access == "R":
            self._note(f, READ_ONLY, f"{par.id} {par.name}: the manual says it cannot be set (l.{par.line})", *span)
        if (par.min is not None and raw < par.min) or (par.max is not None and raw > par.max):
            self._note(f, RANGE, f"{par.id} = {raw}, set range {par.min}..{par.max} (l.{par.line})", *span)
        if par.access == "RW" and not par.running and state.extra.get("running"):
            self._note(f, RUNNING, f"{par.id} is not marked ** and the last CNST said running", *span)

    def _control(self, f, role, p, state) -> None:
        if role == REQUEST:
            v = _byte(p.cntr, CNTR_BITS)
            f.points = [{"name": "CNTR", "address": None, "raw": v, "value": v, "unit": None,
                         "text": bits_text(CNTR_BITS, v), "span": [3, 4]}]
            f.summary = f"control CNTR={v:02X}H [{bits_text(CNTR_BITS, v)}]"
            return
        v = _byte(p.cnst, CNST_BITS)
        f.points = [{"name": "CNST", "address": None, "raw": v, "value": v, "unit": None,
                     "text": bits_text(CNST_BITS, v), "span": [3, 4]}]
        f.summary = f"control status CNST={v:02X}H [{bits_text(CNST_BITS, v)}]"
        if f.crc_ok:
            state.extra["running"] = bool(p.cnst.running or p.cnst.jogging)

    def _status(self, f, role, p, request, state, k) -> None:
        if role == REQUEST:
            cfg = p.cfg
            st = STATUS.get(cfg)
            if st is None:
                self._note(f, STATUS_CFG, f"CFG={cfg}", 3, 4)
            f.summary = f"read status CFG {cfg}" + (f" ({st.label}: {st.name})" if st else "")
            return
        cfg = p.cfg if "cfg" in p else None
        if cfg is None and request is not None and request.crc_ok and len(request.adu) >= 4:
            cfg = request.adu[3]
        if cfg is None:
            self._note(f, NO_REQUEST, "status value without CFG: selector unknown", 3, len(f.adu))
        st = STATUS.get(cfg) if cfg is not None else None
        if cfg is not None and st is None:
            self._note(f, STATUS_CFG, f"CFG={cfg}", 3, len(f.adu))
        raw = p.value
        span = [4, 6] if k == 3 else [3, 3 + k]  # after the CFG echo, or the value alone
        if st is None:
            pt = {"name": f"status CFG {cfg}" if cfg is not None else "status", "address": cfg, "raw": raw,
                  "value": raw, "unit": None, "span": span}
        else:
            value = raw if st.scale is None else round(raw * st.scale, 2)
            pt = {"name": st.label, "address": cfg, "raw": raw, "value": value, "unit": st.unit,
                  "id": f"CFG{cfg}", "span": span}
            if st.scale is None:
                pt["text"] = f"{st.name}; scale not given by the manual"
            if f.crc_ok:
                state.commit(f, PD_TABLES[0x04], cfg, [raw])
        f.points = [pt]
        f.summary = _pt_text(pt)

    def _error(self, f, fc, data, request, state) -> None:
        err = ERRORS[fc]
        f.exception = {"code": fc, "name": err.name}
        if request is not None and len(request.adu) >= 2 and request.adu[1] in FUNCTIONS:
            to = FUNCTIONS[request.adu[1]].name
        elif f.function == 0x82:
            to = FUNCTIONS[0x02].name
        else:
            to = " or ".join(FUNCTIONS[a].name for a in err.answers)
        self._note(f, ERROR_REPLY, f"{fc:02X}H: {err.name} (l.{err.line}), answering {to}", 1, 2)
        if not data:
            self._note(f, DATA_SHORT, f"{fc:02X}H without its data byte", 2, 3)
            f.summary = f"error {fc:02X}H {err.name} ({to})"
            return
        if fc == 0x81:
            par = PARAMS.get(data[0])
            what = f"{par.id} {par.name}" if par else f"PD{data[0]:03d}"
        else:
            what = f"CNST={data[0]:02X}H [{bits_text(CNST_BITS, data[0])}]"
            f.points = [{"name": "CNST", "address": None, "raw": data[0], "value": data[0], "unit": None,
                         "text": bits_text(CNST_BITS, data[0]), "span": [3, 4]}]
        f.summary = f"error {fc:02X}H {err.name} ({to}): {what}"
        if len(data) > 1:
            self._note(f, DATA_EXTRA, f"{len(data) - 1} byte(s) after the error reply's data byte", 4, 3 + len(data))

    # ---------------------------------------------------------------- pairing
    def _check_pair(self, f: Frame, fc: int, request: Frame | None) -> None:
        problem = None
        if request is not None and request.crc_ok and f.crc_ok:
            rq, rs = request.adu, f.adu
            if fc in (0x01, 0x02, 0x81) and len(rq) >= 4 and len(rs) >= 4 and rq[3] != rs[3]:
                problem = f"reply is about PD{rs[3]:03d}, the request about PD{rq[3]:03d}"
            elif fc == 0x04 and len(rs) == 6 and len(rq) >= 4 and rq[3] != rs[3]:
                problem = f"reply carries CFG {rs[3]}, the request asked CFG {rq[3]}"
            elif fc == 0x08 and rs[2:] != rq[2:]:
                self._note(f, LOOP_ECHO, f"sent {rq[3:].hex() or '-'}, got {rs[3:].hex() or '-'}", 2, len(f.adu))
        if problem:
            self._note(f, core.PAIR_MISMATCH, "PD: " + problem, 0, len(f.adu))


def _byte(parsed, bits) -> int:
    return sum(1 << b.bit for b in bits if parsed[b.name])


def _pt_text(pt: dict) -> str:
    unit = pt.get("unit")
    value = pt["value"]
    shown = f"{value:.2f}" if isinstance(value, float) else str(value)
    text = pt.get("text")
    return f"{pt['name']} = {shown}{' ' + unit if unit else ''}{' [' + text + ']' if text else ''}"


__all__ = ["PdSeriesDecoder", "load", "DECODER_CODES"]
