"""Generic Modbus decoder: every standard function code, registers by number.

Drive models subclass GenericModbus and override `point()` (and `check_*`
hooks) to give registers their manual names, scales and units; the walking
of requests, responses, exceptions and the register shadow stays here.
"""

from __future__ import annotations

import functools

from construct import ConstructError

from sniffer.codes import (
    COIL_VALUE, DECODE_SHORT, EXCEPTION, NO_REQUEST_CONTEXT, QUANTITY, Code, note, note_in,
)
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.protocols import MODBUS_TABLES

from ..base import UnitState
from .fast import FAST
from .schema import EXCEPTION_NAMES, FUNCTION_NAMES, LAYOUTS


SPACE = MODBUS_TABLES  # function code -> "coil" / "discrete" / "holding" / "input"
_MAX_QTY = {0x01: 2000, 0x02: 2000, 0x03: 125, 0x04: 125, 0x0F: 1968, 0x10: 123}


class GenericModbus:
    model = "generic"
    codes: tuple[Code, ...] = (EXCEPTION, DECODE_SHORT, NO_REQUEST_CONTEXT, COIL_VALUE, QUANTITY)

    # ---- hooks for drive models --------------------------------------------
    def point(self, space: str, address: int | None, raw: int, state: UnitState) -> dict:
        """One decoded value. Models map (space, address) to name/scale/unit."""
        name = f"{space}[{address}]" if address is not None else f"{space}[?]"
        return {"name": name, "address": address, "raw": raw, "value": raw, "unit": None}

    def make_points(self, space: str, addr: int | None, values: list[int], state: UnitState) -> list[dict]:
        """Points for consecutive registers or bits of one space (a model may override it to join 32-bit values)."""
        point = self.point
        if addr is None:
            return [point(space, None, v, state) for v in values]
        if type(self).point is GenericModbus.point:  # no model: skip the per-register call
            return [
                {"name": nm, "address": a, "raw": v, "value": v, "unit": None}
                for nm, a, v in zip(_names(space, addr, len(values)), range(addr, addr + len(values)), values)
            ]
        return [point(space, addr + i, v, state) for i, v in enumerate(values)]

    # ---- decode ----------------------------------------------------------
    def decode(self, f: Frame, request: Frame | None, state: UnitState) -> None:
        adu = f.adu  # unit + PDU, without CRC/LRC: spans below are ADU offsets
        fc = f.function
        if fc is None or len(adu) < 2:
            return
        body = adu[2:]
        if fc & 0x80:
            self._exception(f, fc, body)
            return
        role = RESPONSE if f.role == RESPONSE else REQUEST
        hot = self._hot.get((fc, role))
        if hot is None:  # no handler: a function code we only name
            f.summary = (f"{FUNCTION_NAMES[fc]} {role}" if fc in FUNCTION_NAMES
                         else f"function 0x{fc:02X} ({len(body)} data bytes)")
            return
        reader, handler = hot
        parsed = reader(body)
        if parsed is None:
            f.annotations.append(
                note_in(DECODE_SHORT, f"{len(body)} data bytes too few for {FUNCTION_NAMES.get(fc, hex(fc))}",
                        2, max(3, len(adu)), len(f.raw))
            )
            f.summary = f"{FUNCTION_NAMES.get(fc, hex(fc))} (malformed)"
            return
        handler(f, role, parsed, request, state)

    @functools.cached_property
    def _hot(self) -> dict:
        """(function, role) -> (body reader, bound handler): one lookup per frame, subclass overrides kept."""
        out = {}
        for (fc, role), layout in LAYOUTS.items():
            name = _handler_name(fc, role)
            if name is not None:
                out[fc, role] = (FAST.get((fc, role)) or _construct_reader(layout), getattr(self, name))
        return out

    def _exception(self, f: Frame, fc: int, body: bytes) -> None:
        code = body[0] if body else None
        name = EXCEPTION_NAMES.get(code, "UNKNOWN EXCEPTION") if code is not None else "MISSING CODE"
        f.exception = {"code": code, "name": name}
        base = FUNCTION_NAMES.get(fc & 0x7F, f"function 0x{fc & 0x7F:02X}")
        f.summary = f"exception {code:02X} {name} ({base})" if code is not None else f"exception ({base})"
        f.annotations.append(note_in(EXCEPTION, f"{code} {name}", 2, 3, len(f.raw)))

    # ---- per-function handlers ---------------------------------------------
    def _read_req(self, f, role, p, request, state):
        fc = f.function
        a, q = p["address"], p["quantity"]
        f.summary = f"read {SPACE[fc]} {a}..{a + q - 1} ({q})"
        if not 1 <= q <= _MAX_QTY[fc]:
            self._check_qty(f, fc, q)

    def _read_regs_rsp(self, f, role, p, request, state):
        fc = f.function
        values = p["values"]
        space = SPACE[fc]
        addr = None
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            addr = (request.adu[2] << 8) | request.adu[3]
        else:
            f.annotations.append(note(NO_REQUEST_CONTEXT, "register numbers unknown", 2, len(f.adu)))
        shadow = state.holding if fc in (0x03, 0x17) else state.input
        if addr is not None and f.crc_ok:  # the shadow holds what CRC-good frames said
            shadow.update(zip(range(addr, addr + len(values)), values))
        pts = self.make_points(space, addr, values, state)
        f.points = pts
        f.summary = _points_summary(pts)

    def _read_bits_rsp(self, f, role, p, request, state):
        fc = f.function
        space = SPACE[fc]
        status = p["status"]
        addr, qty = None, len(status) * 8
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            addr = (request.adu[2] << 8) | request.adu[3]
            qty = min(qty, (request.adu[4] << 8) | request.adu[5])
        else:
            f.annotations.append(note(NO_REQUEST_CONTEXT, "bit numbers unknown", 2, len(f.adu)))
        shadow = state.coils if fc == 0x01 else state.discrete
        bits = [(status[i >> 3] >> (i & 7)) & 1 for i in range(qty)]
        if addr is not None and f.crc_ok:
            shadow.update(zip(range(addr, addr + qty), bits))
        pts = self.make_points(space, addr, bits, state)
        f.points = pts
        f.summary = _points_summary(pts)

    def _write_single(self, f, role, p, request, state):
        fc = f.function
        a, v = p["address"], p["value"]
        if fc == 0x05:
            if v not in (0xFF00, 0x0000):
                f.annotations.append(note(COIL_VALUE, f"value 0x{v:04X}", 4, 6))
            bit = 1 if v == 0xFF00 else 0
            pt = self.point("coil", a, bit, state)
            if f.crc_ok and (role == RESPONSE or f.unit == 0):
                state.coils[a] = bit
        else:
            pt = self.point("holding", a, v, state)
            if f.crc_ok and (role == RESPONSE or f.unit == 0):
                state.holding[a] = v
        f.points = [pt]
        verb = "write" if role == REQUEST else "wrote"
        f.summary = f"{verb} {_pt_text(pt)}"

    def _write_multi_req(self, f, role, p, request, state):
        fc = f.function
        a, q = p["address"], p["quantity"]
        self._check_qty(f, fc, q)
        pts = []
        if fc == 0x0F:
            vals = p["values"]
            for i in range(min(q, len(vals) * 8)):
                pts.append(self.point("coil", a + i, (vals[i >> 3] >> (i & 7)) & 1, state))
        else:
            pts = self.make_points("holding", a, list(p["values"]), state)
        if f.unit == 0 and f.crc_ok:
            self._commit(pts, fc, state)
        f.points = pts
        f.summary = "write " + _points_summary(pts)

    def _write_multi_rsp(self, f, role, p, request, state):
        fc = f.function
        a, q = p["address"], p["quantity"]
        f.summary = f"wrote {SPACE[fc]} {a}..{a + q - 1} ({q})"
        if request is not None and request.points and request.crc_ok and f.crc_ok:
            self._commit(request.points, fc, state)

    def _commit(self, pts, fc, state):
        shadow = state.coils if fc == 0x0F else state.holding
        for pt in pts:
            if pt["address"] is not None:
                shadow[pt["address"]] = pt["raw"]

    def _other(self, f, role, p, request, state):
        fc = f.function
        items = ", ".join(f"{k}={_short(v)}" for k, v in p.items() if not k.startswith("_"))
        f.summary = f"{FUNCTION_NAMES[fc]} {role}: {items}" if items else f"{FUNCTION_NAMES[fc]} {role}"
        if fc == 0x16 and role == RESPONSE and f.crc_ok:
            a = p["address"]
            old = state.holding.get(a)
            if old is not None:
                state.holding[a] = (old & p["and_mask"]) | (p["or_mask"] & ~p["and_mask"] & 0xFFFF)
        if fc == 0x17 and role == REQUEST:
            f.points = [self.point("holding", p["write_address"] + i, v, state) for i, v in enumerate(p["values"])]

    def _rw_rsp(self, f, role, p, request, state):
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            addr = (request.adu[2] << 8) | request.adu[3]
            f.points = [self.point("holding", addr + i, v, state) for i, v in enumerate(p["values"])]
            if f.crc_ok:
                for pt in f.points:
                    state.holding[pt["address"]] = pt["raw"]
            f.summary = _points_summary(f.points)
        else:
            self._read_regs_rsp(f, role, p, None, state)

    def _check_qty(self, f, fc, q):
        hi = _MAX_QTY.get(fc)
        if hi is not None and not 1 <= q <= hi:
            f.annotations.append(note(QUANTITY, f"quantity {q} (allowed 1..{hi})", 4, 6))


def _handler_name(fc: int, role: str) -> str | None:
    """The method that decodes a parsed body of this function and role (None: name it only)."""
    if fc not in FUNCTION_NAMES:
        return None
    if fc in (0x01, 0x02, 0x03, 0x04) and role == REQUEST:
        return "_read_req"
    if fc in (0x03, 0x04):
        return "_read_regs_rsp"
    if fc in (0x01, 0x02):
        return "_read_bits_rsp"
    if fc in (0x05, 0x06):
        return "_write_single"
    if fc in (0x0F, 0x10):
        return "_write_multi_req" if role == REQUEST else "_write_multi_rsp"
    if fc == 0x17 and role == RESPONSE:
        return "_rw_rsp"
    return "_other"


def _construct_reader(layout):
    """A construct layout as a reader: the parsed Container, or None where the body does not fit."""

    def read(body: bytes):
        try:
            return layout.parse(body)
        except (ConstructError, ValueError, IndexError, OverflowError):
            return None

    return read


_NAME_CACHE: dict[tuple[str, int, int], list[str]] = {}


def _names(space: str, addr: int, n: int) -> list[str]:
    """Cached names of a register block: polls read the same blocks over and over."""
    key = (space, addr, n)
    names = _NAME_CACHE.get(key)
    if names is None:
        if len(_NAME_CACHE) > 4096:
            _NAME_CACHE.clear()
        names = _NAME_CACHE[key] = [f"{space}[{a}]" for a in range(addr, addr + n)]
    return names


def _pt_text(pt: dict) -> str:
    unit = pt["unit"]
    text = pt.get("text")
    if not unit and not text:
        return f"{pt['name']}={pt['value']}"
    return f"{pt['name']}={pt['value']}{' ' + unit if unit else ''}{' [' + text + ']' if text else ''}"


def _points_summary(pts: list[dict], limit: int = 6) -> str:
    text = " ".join([f"{p['name']}={p['value']}" if not p["unit"] and not p.get("text") else _pt_text(p)
                     for p in pts[:limit]])
    if len(pts) > limit:
        text += f" ... (+{len(pts) - limit})"
    return text


def _short(v) -> str:
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    if isinstance(v, list):
        return "[" + ",".join(_short(x) for x in v[:8]) + ("...]" if len(v) > 8 else "]")
    return str(v)
