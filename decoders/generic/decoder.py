"""Generic Modbus decoder: every standard function code, registers by number.

Drive models subclass GenericModbus and override `point()` (and `check_*`
hooks) to give registers their manual names, scales and units; the walking
of requests, responses, exceptions and the register shadow stays here.
"""

from __future__ import annotations

import functools
from struct import Struct, unpack_from

from sniffer.codes import (
    BITS_PADDING, BYTE_COUNT_ODD, COIL_VALUE, DECODE_SHORT, EXCEPTION, EXCEPTION_UNLISTED, NO_REQUEST_CONTEXT,
    QUANTITY, Code, note, note_in,
)
from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.hot import HOT
from sniffer.protocols import MODBUS_MAX_QUANTITY, MODBUS_TABLES, TABLE_END, modbus_range_ok

from ..base import UnitState
from .block import BIT_SPACES, RegisterBlock, spans
from .names import EXCEPTION_NAMES, FUNCTION_NAMES


SPACE = MODBUS_TABLES  # function code -> "coil" / "discrete" / "holding" / "input"


class GenericModbus:
    model = "generic"
    codes: tuple[Code, ...] = (EXCEPTION, EXCEPTION_UNLISTED, DECODE_SHORT, NO_REQUEST_CONTEXT, COIL_VALUE, QUANTITY,
                               BITS_PADDING, BYTE_COUNT_ODD)

    # ---- hooks for drive models --------------------------------------------
    def point(self, space: str, address: int | None, raw: int, state: UnitState) -> dict:
        """One decoded value. Models map (space, address) to name/scale/unit."""
        name = f"{space}[{address}]" if address is not None else f"{space}[?]"
        return {"name": name, "address": address, "raw": raw, "value": raw, "unit": None}

    def range_text(self, space: str, a: int, q: int) -> str:
        """How a summary names `q` registers or bits from `a`: generic numbers them in decimal;
        a model names them as its manual does (TableDecoder: hex and parameter ids).  Asked only for
        a range the function can name (`_range`)."""
        return f"{space} {a}..{a + q - 1} ({q})"

    def _range(self, fc: int, a: int, q: int) -> str:
        """A frame's address and quantity fields in a summary: a range where the function can name it,
        else only where it starts (the quantity annotation says what the field holds): no summary names
        a register past 65535 or a count the function cannot carry (CRC-bad junk: `holding from 33667`)."""
        space = SPACE[fc]
        if modbus_range_ok(fc, a, q):
            return self.range_text(space, a, q)
        hi = MODBUS_MAX_QUANTITY.get(fc, TABLE_END)
        return f"{space} from {a} ({'quantity out of range' if not 1 <= q <= hi else 'runs past 65535'})"

    def _first_address(self, f: Frame, addr: int | None, n: int) -> int | None:
        """`addr` for `n` consecutive values, or None (their numbers unknown, annotated) when they would run
        past 65535: no point, shadow write or filter range names a register that cannot exist."""
        if addr is None or addr + n <= TABLE_END:
            return addr
        f.annotations.append(note_in(QUANTITY, f"{n} values from {addr} run past 65535: their numbers are unknown",
                                     2, 6, len(f.raw)))
        return None

    def make_points(self, space: str, addr: int | None, values: list[int], state: UnitState,
                    offset: int) -> list[dict]:
        """Points for consecutive registers or bits of one space, each with its span.

        `offset` is the ADU offset of the first value's bytes: register i is at
        [offset + 2i, offset + 2i + 2), bit i in the byte offset + i // 8.  A model
        may override it (to join 32-bit values: that point's span covers both words).
        """
        if addr is None:
            pts = [self.point(space, None, v, state) for v in values]
        else:
            point = self.point
            pts = [point(space, a, v, state) for a, v in zip(range(addr, addr + len(values)), values)]
        for pt, sp in zip(pts, spans(offset, len(values), space in BIT_SPACES)):
            pt["span"] = sp
        return pts

    def _points(self, space: str, addr: int | None, values: list[int], state: UnitState, offset: int):
        """make_points, or with no model (neither hook overridden) a RegisterBlock: the same points,
        built only if someone reads them (decoders.generic.block)."""
        if self._plain and addr is not None:
            return RegisterBlock(space, addr, values, offset)
        return self.make_points(space, addr, values, state, offset)

    @functools.cached_property
    def _plain(self) -> bool:
        cls = type(self)
        return cls.point is GenericModbus.point and cls.make_points is GenericModbus.make_points

    # ---- decode ----------------------------------------------------------
    def decode(self, f: Frame, request: Frame | None, state: UnitState) -> None:
        """decode_py, in C for the plain decoder's common frames (sniffer/_hot.c generic_fast)."""
        fast = self._compiled
        if fast is None or fast(f, request, state, _HOT_CTX) is NotImplemented:
            self.decode_py(f, request, state)

    @functools.cached_property
    def _compiled(self):
        """sniffer._hot.generic_fast for the generic decoder itself (a model's hooks run in Python), else None."""
        return HOT.generic_fast if HOT is not None and type(self) is GenericModbus else None

    def decode_py(self, f: Frame, request: Frame | None, state: UnitState) -> None:
        """The reference of decode (tests/test_hot_equal.py holds the two alike)."""
        adu = f.adu  # unit + PDU, without CRC/LRC: spans below are ADU offsets
        fc = f.function
        if fc is None or len(adu) < 2:
            return
        if fc & 0x80:
            self._exception(f, fc, adu[2:])
            return
        handler = (self._on_response if f.role == RESPONSE else self._on_request).get(fc)
        if handler is None:  # no handler: a function code we only name
            role = RESPONSE if f.role == RESPONSE else REQUEST
            f.summary = (f"{FUNCTION_NAMES[fc]} {role}" if fc in FUNCTION_NAMES
                         else f"function 0x{fc:02X} ({len(adu) - 2} data bytes)")
            return
        handler(f, adu, request, state)

    @functools.cached_property
    def _on_request(self) -> dict:
        """function -> bound handler(f, adu, request, state) for requests (and unknown roles)."""
        return self._handlers(REQUEST)

    @functools.cached_property
    def _on_response(self) -> dict:
        return self._handlers(RESPONSE)

    def _handlers(self, role: str) -> dict:
        """The traffic of nearly every line (0x01-0x06, 0x0F, 0x10) is read from the ADU in place by
        one method each; the other codes are parsed by their construct layout, then handled."""
        out = {}
        for fc in FUNCTION_NAMES:  # each has a layout both ways (schema.py)
            inline = _INLINE.get((fc, role))
            out[fc] = getattr(self, inline) if inline else functools.partial(
                self._parsed, _construct_reader(fc, role), getattr(self, _handler_name(fc, role)), role)
        return out

    def _parsed(self, reader, handler, role, f, adu, request, state):
        parsed = reader(adu[2:])
        if parsed is None:
            self._malformed(f, adu)
            return
        handler(f, role, parsed, request, state)

    def _malformed(self, f: Frame, adu: bytes) -> None:
        fc = f.function
        f.annotations.append(
            note_in(DECODE_SHORT, f"{len(adu) - 2} data bytes too few for {FUNCTION_NAMES.get(fc, hex(fc))}",
                    2, max(3, len(adu)), len(f.raw))
        )
        f.summary = f"{FUNCTION_NAMES.get(fc, hex(fc))} (malformed)"

    def exception_info(self, code: int) -> tuple[str, str, str | None]:
        """(name, detail, why unlisted or None) of exception `code`: one table is the source (here the
        Modbus standard's; a drive model's is its manual's). Codes in hex, as the tables print them."""
        name = EXCEPTION_NAMES.get(code)
        if name is not None:
            return name, f"{code:02X}H {name}", None
        why = f"{code:02X}H is not a standard Modbus exception code"
        return "UNKNOWN EXCEPTION", f"{code:02X}H UNKNOWN EXCEPTION", why

    def _exception(self, f: Frame, fc: int, body: bytes) -> None:
        base = FUNCTION_NAMES.get(fc & 0x7F, f"function 0x{fc & 0x7F:02X}")
        n = len(f.raw)
        if not body:
            f.exception = {"code": None, "name": "MISSING CODE"}
            f.summary = f"exception ({base})"
            f.annotations.append(note_in(EXCEPTION, "exception response without its code byte", 1, 2, n))
            return
        code = body[0]
        name, detail, unlisted = self.exception_info(code)
        f.exception = {"code": code, "name": name}
        f.summary = f"exception {code:02X}H {name} ({base})"
        f.annotations.append(note_in(EXCEPTION, detail, 2, 3, n))
        if unlisted:
            f.annotations.append(note_in(EXCEPTION_UNLISTED, unlisted, 2, 3, n))

    # ---- per-function handlers ---------------------------------------------
    # Spans below are ADU offsets: unit fc | address(2) quantity(2) | ... ; a read response's
    # values start at 3 (after the byte count), a multiple write's at 7, 0x17's written ones at 11.
    # The shadow is written only through state.commit, which records the write on the frame.
    # The hot handlers read the ADU in place, with the length rules of schema.py's layouts
    # (test_generic_inline checks them against those on random bodies and the reference vectors).
    def _read_req(self, f, adu, request, state):  # 0x01-0x04 request: address, quantity
        if len(adu) < 6:
            self._malformed(f, adu)
            return
        fc = f.function
        a, q = _HH.unpack_from(adu, 2)
        f.summary = "read " + self._range(fc, a, q)
        self._check_qty(f, fc, q)

    def _read_regs_rsp(self, f, adu, request, state):  # 0x03 / 0x04 (and 0x17) response: count, words
        n = len(adu)
        k = adu[2] >> 1 if n > 2 else 0
        if n < 3 or n < 3 + 2 * k:
            self._malformed(f, adu)
            return
        values = list(_WORDS[k].unpack_from(adu, 3))
        if adu[2] & 1:
            f.annotations.append(note(BYTE_COUNT_ODD, f"byte count {adu[2]}: {k} registers and one byte more",
                                      2, min(n, 3 + adu[2])))
        space = SPACE[f.function]
        addr = None
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            addr = self._first_address(f, (request.adu[2] << 8) | request.adu[3], len(values))
            if f.crc_ok and values and addr is not None:  # the shadow holds what CRC-good frames said
                state.commit(f, space, addr, values)
        else:
            f.annotations.append(note(NO_REQUEST_CONTEXT, "register numbers unknown", 2, n))
        pts = f.points = self._points(space, addr, values, state, 3)
        f.summary = points_summary(pts)

    def _read_bits_rsp(self, f, adu, request, state):  # 0x01 / 0x02 response: count, packed bits
        n = len(adu)
        if n < 3 or n < 3 + adu[2]:
            self._malformed(f, adu)
            return
        space = SPACE[f.function]
        status = adu[3 : 3 + adu[2]]
        addr, qty = None, len(status) * 8
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            addr = (request.adu[2] << 8) | request.adu[3]
            asked = (request.adu[4] << 8) | request.adu[5]
            if asked < qty and int.from_bytes(status, "little") >> asked:  # bit k: byte k // 8, bit k % 8
                f.annotations.append(note(BITS_PADDING, f"bits past the {asked} requested are set", 3, n))
            qty = min(qty, asked)
        else:
            f.annotations.append(note(NO_REQUEST_CONTEXT, "bit numbers unknown", 2, n))
        bits = _bits(status, qty)
        addr = self._first_address(f, addr, len(bits))
        if addr is not None and f.crc_ok and bits:
            state.commit(f, space, addr, bits)
        pts = f.points = self._points(space, addr, bits, state, 3)
        f.summary = points_summary(pts)

    def _write_single(self, f, adu, request, state):  # 0x05 / 0x06, both ways: address, value
        if len(adu) < 6:
            self._malformed(f, adu)
            return
        fc = f.function
        a, v = _HH.unpack_from(adu, 2)
        space = SPACE[fc]
        if fc == 0x05:
            if v not in (0xFF00, 0x0000):
                f.annotations.append(note(COIL_VALUE, f"value 0x{v:04X}", 4, 6))
            v = 1 if v == 0xFF00 else 0
        response = f.role == RESPONSE
        if f.crc_ok and (response or f.unit == 0):  # the response echoes what was written
            state.commit(f, space, a, [v])
        if self._plain:
            f.points = [{"name": f"{space}[{a}]", "address": a, "raw": v, "value": v, "unit": None,
                         "span": [4, 6]}]
            f.summary = f"{'wrote' if response else 'write'} {space}[{a}]={v}"
            return
        pt = self.point(space, a, v, state)
        pt["span"] = [4, 6]
        f.points = [pt]
        f.summary = f"{'wrote' if response else 'write'} {_pt_text(pt)}"

    def _write_multi_req(self, f, adu, request, state):  # 0x0F / 0x10 request: address, quantity, values
        written = _request_values(adu)
        if written is None:
            self._malformed(f, adu)
            return
        fc = f.function
        a, q, values = written
        self._check_qty(f, fc, q)
        space = SPACE[fc]
        a = self._first_address(f, a, len(values))
        pts = self._points(space, a, values, state, 7)
        if f.unit == 0 and f.crc_ok and values and a is not None:  # a broadcast is answered by nobody: written at once
            state.commit(f, space, a, values)
        f.points = pts
        f.summary = "write " + points_summary(pts)

    def _write_multi_rsp(self, f, adu, request, state):  # 0x0F / 0x10 response: address, quantity
        if len(adu) < 6:
            self._malformed(f, adu)
            return
        fc = f.function
        a, q = _HH.unpack_from(adu, 2)
        f.summary = "wrote " + self._range(fc, a, q)
        self._check_qty(f, fc, q)
        # the request's values, confirmed here: only by a response naming the same registers (pair.mismatch
        # otherwise, and nothing is known written)
        if request is not None and request.crc_ok and f.crc_ok and request.adu[2:6] == adu[2:6]:
            written = _request_writes(request, fc)
            if written is not None:
                state.commit(f, *written)

    def _other(self, f, role, p, request, state):
        fc = f.function
        items = ", ".join(f"{k}={_short(v)}" for k, v in p.items() if not k.startswith("_"))
        f.summary = f"{FUNCTION_NAMES[fc]} {role}: {items}" if items else f"{FUNCTION_NAMES[fc]} {role}"
        if fc == 0x16 and f.crc_ok and (role == RESPONSE or f.unit == 0):
            a = p["address"]
            old = state.holding.get(a)
            if old is not None:  # the result needs the register's value before the mask
                state.commit(f, "holding", a, [(old & p["and_mask"]) | (p["or_mask"] & ~p["and_mask"] & 0xFFFF)])
        if fc == 0x17 and role == REQUEST:
            values = list(p["values"])
            f.points = self._points("holding", self._first_address(f, p["write_address"], len(values)), values,
                                    state, 11)

    def _rw_rsp(self, f, role, p, request, state):
        if request is not None and request.crc_ok and len(request.adu) >= 6:
            values = list(p["values"])
            addr = self._first_address(f, (request.adu[2] << 8) | request.adu[3], len(values))
            if f.crc_ok:  # 0x17 writes first, then reads (Modbus 6.17): both parts, in that order
                written = _request_writes(request, 0x17)
                if written is not None:
                    state.commit(f, *written)
                if values and addr is not None:
                    state.commit(f, "holding", addr, values)
            pts = f.points = self._points("holding", addr, values, state, 3)
            f.summary = points_summary(pts)
        else:  # a 0x17 response is laid out as a 0x03 one
            self._read_regs_rsp(f, f.adu, None, state)

    def _check_qty(self, f, fc, q):
        hi = MODBUS_MAX_QUANTITY.get(fc)
        if hi is not None and not 1 <= q <= hi:
            f.annotations.append(note(QUANTITY, f"quantity {q} (allowed 1..{hi})", 4, 6))


# (function, role) -> the method that reads it from the ADU in place
_INLINE = {
    **{(fc, REQUEST): "_read_req" for fc in (0x01, 0x02, 0x03, 0x04)},
    (0x03, RESPONSE): "_read_regs_rsp", (0x04, RESPONSE): "_read_regs_rsp",
    (0x01, RESPONSE): "_read_bits_rsp", (0x02, RESPONSE): "_read_bits_rsp",
    **{(fc, r): "_write_single" for fc in (0x05, 0x06) for r in (REQUEST, RESPONSE)},
    (0x0F, REQUEST): "_write_multi_req", (0x10, REQUEST): "_write_multi_req",
    (0x0F, RESPONSE): "_write_multi_rsp", (0x10, RESPONSE): "_write_multi_rsp",
}
# what generic_fast reads besides the frame: the role word, the block and state types, the two tables by function
_HOT_CTX = (RESPONSE, RegisterBlock, UnitState, tuple(SPACE.get(fc) for fc in range(256)),
            tuple(MODBUS_MAX_QUANTITY.get(fc) for fc in range(256)))
_HH = Struct(">HH")
_WORDS = tuple(Struct(f">{k}H") for k in range(128))  # a byte count's words: 0..127
_BITS = tuple(tuple((b >> i) & 1 for i in range(8)) for b in range(256))  # a byte's bits, LSB first


def _bits(status: bytes, qty: int) -> list[int]:
    """The first `qty` bits of packed coil / input status bytes, as 0/1."""
    out: list[int] = []
    for b in status:
        out += _BITS[b]
    del out[qty:]
    return out


def _request_values(adu: bytes) -> tuple[int, int, list[int]] | None:
    """(address, quantity, values) of a 0x0F / 0x10 request ADU, or None where its body is too short:
    coils as 0/1 (as many as both the quantity and the bytes give), registers as the words present."""
    n = len(adu)
    if n < 7:
        return None
    nb = adu[6]
    a, q = _HH.unpack_from(adu, 2)
    if adu[1] == 0x0F:
        if n < 7 + nb:
            return None
        return a, q, _bits(adu[7 : 7 + nb], min(q, nb * 8))
    k = nb >> 1
    if n < 7 + 2 * k:
        return None
    return a, q, list(_WORDS[k].unpack_from(adu, 7))


def _handler_name(fc: int, role: str) -> str:
    """The method that handles a body its construct layout parsed (codes without an inline reader)."""
    if fc == 0x17 and role == RESPONSE:
        return "_rw_rsp"
    return "_other"


def _construct_reader(fc: int, role: str):
    """The construct layout of (fc, role) as a reader: the parsed Container, or None where the body
    does not fit.  construct is imported on the first call (schema.py)."""
    layout = None

    def read(body: bytes):
        nonlocal layout
        from construct import ConstructError

        if layout is None:
            from .schema import LAYOUTS

            layout = LAYOUTS[fc, role]
        try:
            return layout.parse(body)
        except (ConstructError, ValueError, IndexError, OverflowError):
            return None

    return read


def _request_writes(request: Frame, fc: int) -> tuple[str, int, list[int]] | None:
    """(table, start, values) a CRC-good write request (0x0F, 0x10, 0x17) asked for, read from its bytes."""
    if request.function != fc:
        return None
    adu = request.adu
    if fc == 0x17:
        body = adu[2:]
        if len(body) < 9:
            return None
        n = body[8] // 2
        if len(body) < 9 + 2 * n or not n:
            return None
        a = (body[4] << 8) | body[5]
        return ("holding", a, list(unpack_from(f">{n}H", body, 9))) if a + n <= TABLE_END else None
    written = _request_values(adu)
    if written is None or not written[2] or written[0] + len(written[2]) > TABLE_END:
        return None
    return SPACE[fc], written[0], written[2]


def _pt_text(pt: dict) -> str:
    unit = pt["unit"]
    text = pt.get("text")
    if pt["value"] is None:  # a marker value, no measurement (TableDecoder: not available)
        return f"{pt['name']}=n/a [{text}]"
    if not unit and not text:
        return f"{pt['name']}={pt['value']}"
    return f"{pt['name']}={pt['value']}{' ' + unit if unit else ''}{' [' + text + ']' if text else ''}"


def points_summary(pts, limit: int = 6) -> str:
    if type(pts) is RegisterBlock:
        return pts.summary(limit)
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
