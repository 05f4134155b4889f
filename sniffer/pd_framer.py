"""PD-series inverter framers: RTU (ADDR FUNC LEN DATA CRC-16) and ASCII (':' hex LRC CR LF).

The PD-series protocol (shared/manuals/pd-series-protocol.txt, "l.N" = line N)
only looks like Modbus.  Every frame is ADDR FUNC LEN DATA + check (l.64,
l.203); LEN counts the bytes between LEN and the check (our reading of l.181 /
l.107, see decoders/pd_series/NOTES.md), so the frame length is LEN + 5 in
RTU.  Sans-I/O and the same interface as RtuFramer / AsciiFramer, whose
buffer, timestamps and silences these classes reuse.

RTU (`PdRtuFramer`, protocol "pd-rtu"):
  * the quiet time between frames is > 50 ms (l.203-206), not t3.5: it is the
    HARD silence for per-byte times (`hard_ns`); a frame never spans it.  A
    shorter silence (>= 1.5 characters, or a new USB read) is SOFT: a likely
    boundary that a frame may span.  The manual has no inter-character rule,
    so `modbus.timing.t15` is never emitted (t15_ns = the quiet time).
  * at each frame start, in this order (`_step`):
      A. LEN + 5 bytes with a good CRC (known function): a frame.  This cuts
         glued frames and rejoins frames split across reads.  (A frame ending
         in 00 also checks one byte shorter: `_settle_zero_end` decides.)
      B1. lenient LEN: the shortest run with a good CRC that ends at the next
         boundary, or right before another good frame (glued in one read), or
         before a run of 0x00 bytes (a CRC residual stays 0 through zeros).
         Taken as a frame and annotated `pd.len.mismatch` when LEN disagrees:
         the manual's own examples print LENs that do not count their DATA
         (l.173, l.175).
      B2. a good frame starts later before the boundary: the bytes before it
         are noise.
      B3. LEN + 5 ends exactly at the boundary (or, with per-read times, at a
         later read boundary): a damaged frame, bad CRC.
      B4. a whole burst between two quiets with a known function: a
         malformed frame (bad CRC, `pd.len.mismatch` when LEN disagrees).
      B5. otherwise noise up to the boundary.
ASCII (`PdAsciiFramer`, protocol "pd-ascii"): ':' ... LF as in Modbus ASCII;
`raw` keeps the characters, `adu` the binary ADDR..DATA without the LRC.  The
LRC is the manual's (l.187): 100H minus the byte sum of ADDR..DATA, mod 256.

Both framers set unit, function, adu and can (CAN_REQ/CAN_RSP).  Error replies
81H/83H can only be responses; unit 0 (broadcast, l.71) only a request.  The
manual answers a failed *write* (02H) with 81H too (l.123-125), not 82H: the
pairer pairs on unit + function | 80H, so an 81H that follows a 02H frame of
the same unit gets `function = 0x82` as its pairing key (`pd.error.write`
says so; `raw`/`adu` keep the wire byte 81H).  A bad CRC or LRC is the core
`modbus.crc.mismatch` (same CRC-16 as Modbus, l.217-222) with the expected
value in `crc_expected`.
"""

from __future__ import annotations

from binascii import Error as HexError
from binascii import unhexlify

from fastcrc.crc16 import modbus as crc16_modbus  # incremental: `initial` = the running register

from . import codes
from .ascii_framer import AsciiFramer
from .codes import LINE_CODES, note
from .codes import CRC_MISMATCH
from .codes import PD_BAD_HEX as BAD_HEX
from .codes import PD_FUNCTION_UNKNOWN as FUNCTION_UNKNOWN
from .codes import PD_LEN_MISMATCH as LEN_MISMATCH
from .codes import PD_NO_CRLF as NO_CRLF
from .codes import PD_QUIET_SHORT as QUIET_SHORT
from .codes import PD_WRITE_ERROR as WRITE_ERROR
from .crc import crc_expected, crc_found, crc_ok, lrc
from .frame import CAN_REQ, CAN_RSP, Frame
from .framer import _WAIT, HARD, RtuFramer

QUIET_NS = 50_000_000  # l.203-206: "the time of no data is more than 50 ms"
MIN_FRAME = 5  # ADDR FUNC LEN + CRC (LEN = 0)
MAX_UNIT = 250  # l.73: 01~250 inverters, 00 broadcast
# Function codes only, for framing; decoders/pd_series/schema.py describes each one
# (tests/test_pd_series.py checks that both name the same codes).
FUNCTIONS = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x08})  # l.77-91
RESERVED = frozenset({0x06, 0x07})  # l.87-89
ERRORS = frozenset({0x81, 0x83})  # error replies (l.111, l.125, l.153)
KNOWN = FUNCTIONS | ERRORS

RTU_CODES = LINE_CODES + (CRC_MISMATCH, LEN_MISMATCH, QUIET_SHORT, FUNCTION_UNKNOWN, WRITE_ERROR)
ASCII_CODES = LINE_CODES + (CRC_MISMATCH, LEN_MISMATCH, FUNCTION_UNKNOWN, WRITE_ERROR, NO_CRLF, BAD_HEX)


def roles(unit: int, fc: int) -> int:
    """CAN_REQ/CAN_RSP from the header: requests and replies share one layout."""
    if fc & 0x80:
        return CAN_RSP
    if unit == 0:
        return CAN_REQ
    return CAN_REQ | CAN_RSP


class _PdCommon:
    """What both PD framers add to their Modbus base: the header, LEN check, pairing key, noise text."""

    def __init__(self, line, *, read_slack_ns: int = 50_000_000) -> None:
        super().__init__(line, read_slack_ns=read_slack_ns)
        self.hard_ns = QUIET_NS
        self.t15_ns = QUIET_NS  # no inter-character rule in the manual
        self._last: tuple[int, int] | None = None  # (unit, wire function) of the last frame

    def _span(self, i: int, j: int) -> tuple[int, int]:
        """Byte span of ADU bytes [i, j) inside raw (identity for RTU)."""
        return i, j

    def _fill(self, fr: Frame, adu: bytes, crc_good: bool) -> None:
        unit, fc = adu[0], adu[1]
        fr.unit, fr.function, fr.adu = unit, fc, adu
        fr.can = roles(unit, fc)
        if fc == 0x81 and self._last == (unit, 0x02):
            fr.function = 0x82
            fr.annotations.append(note(WRITE_ERROR, "81H answers the write parameter frame before it "
                                       "(l.123-125): paired as 82H", *self._span(1, 2)))
        self._last = (unit, fc)
        if len(adu) < 3:
            fr.annotations.append(note(LEN_MISMATCH, "no LEN byte", *self._span(1, 2)))
        elif adu[2] != len(adu) - 3:
            how = "taken where the CRC fits" if crc_good else "and the check does not fit either"
            fr.annotations.append(
                note(LEN_MISMATCH, f"LEN={adu[2]:02X}H but {len(adu) - 3} data byte(s) follow ({how})",
                     *self._span(2, 3))
            )
        if fc not in KNOWN:
            what = "reserved (l.87-89)" if fc in RESERVED else "not in l.77-91"
            fr.annotations.append(note(FUNCTION_UNKNOWN, f"function {fc:02X}H is {what}", *self._span(1, 2)))

    def _emit_noise(self, p: int, q: int) -> Frame:
        raw = bytes(self.buf[p - self.base : q - self.base])
        fr = self._new_frame(p, q, "noise", raw)
        fr.noise_reason = self._noise_reason(raw)
        fr.annotations.append(note(codes.NOISE, fr.noise_reason, 0, len(raw)))
        self.pos = q
        return fr


class PdRtuFramer(_PdCommon, RtuFramer):
    protocol = "pd-rtu"
    codes = RTU_CODES

    # ------------------------------------------------------------- decisions
    def _good_at(self, q: int, end: int, final: bool, max_unit: int = 255):
        """Length of a LEN-consistent, CRC-good frame of a known function at q; False; or _WAIT."""
        buf, base = self.buf, self.base
        if buf[q - base] > max_unit or (q + 1 < end and buf[q + 1 - base] not in KNOWN):
            return False
        if q + 2 >= end:
            return False if final else _WAIT
        n = buf[q + 2 - base] + MIN_FRAME
        if q + n > end:
            return False if final else _WAIT
        return n if crc_ok(buf[q - base : q + n - base]) else False

    def _settle_zero_end(self, p: int, e: int, end: int, final: bool):
        """A's frame [p, e) ends in 00: it also checks one byte shorter (see `_lenient_cut`).

        Keep the LEN length unless only the shorter reading leaves a plausible
        start after it (a boundary, a good frame such as a broadcast whose
        address 00 the LEN length swallowed, or a lenient frame).  Only these
        1-in-256 frames wait for what follows.
        """
        if self.buf[e - 1 - self.base] != 0 or e - 1 - p < MIN_FRAME:
            return e
        at = self._plausible_end(e, end, final)
        if at is _WAIT:
            return _WAIT
        if at:
            return e
        short = self._plausible_end(e - 1, end, final)
        if short is _WAIT:
            return _WAIT
        return e - 1 if short else e

    def _lenient_cut(self, p: int, b: int, end: int, final: bool, strict: bool = False):
        """B1: shortest CRC-good run from p that ends at b, before a good frame (or another
        such run: `strict` then asks for a known function and unit), or before zeros.

        CRC-16 cannot tell a frame whose CRC high byte is 00 from the same frame
        one byte shorter: the register after the low CRC byte *is* the high
        byte, and 00 bytes keep a zero register at zero.  A (the LEN length)
        settles that when LEN fits; here, where LEN does not fit, a 00 right
        after the shortest CRC-good run is taken as its CRC high byte only if
        LEN points past the run (as in the manual's l.175, LEN one too long).
        """
        buf, base = self.buf, self.base
        if b - p < MIN_FRAME:
            return False
        unit_ok, fc_ok = buf[p - base] <= MAX_UNIT, buf[p + 1 - base] in KNOWN
        if not (unit_ok and fc_ok if strict else unit_ok or fc_ok):
            return False
        want = p + buf[p + 2 - base] + MIN_FRAME  # where LEN says the frame ends
        reg = crc16_modbus(buf[p - base : p + MIN_FRAME - 1 - base])
        for e in range(p + MIN_FRAME, b + 1):
            reg = crc16_modbus(buf[e - 1 - base : e - base], reg)  # CRC of [p, e): 0 when it checks
            if reg:
                continue
            ends = (e + 1, e) if e < b and buf[e - base] == 0 and want > e else (e,)
            for c in ends:
                if c == b or not any(buf[c - base : b - base]):
                    return c
                nxt = self._good_at(c, end, final, MAX_UNIT)
                if nxt is False:
                    nxt = self._lenient_cut(c, b, end, final, strict=True)
                if nxt is _WAIT:
                    return _WAIT
                if nxt:
                    return c
        return False

    def _step(self, p: int):
        end, final = self._avail(p)
        if p >= end:
            return None
        hit = self._good_at(p, end, final)  # A
        if hit is _WAIT:
            return None
        if hit:
            e = self._settle_zero_end(p, p + hit, end, final)
            return None if e is _WAIT else self._emit(p, e, 0, crc_good=True)
        b = self._next_boundary(p, end, final)
        if b is _WAIT:
            return None
        e = self._lenient_cut(p, b, end, final)  # B1
        if e is _WAIT:
            return None
        if e:
            return self._emit(p, e, 0, crc_good=True)
        q = self._resync(p, b, end, final)  # B2
        if q is _WAIT:
            return None
        if q < b:
            return self._emit_noise(p, q)
        buf, base = self.buf, self.base
        known = b - p >= 3 and buf[p + 1 - base] in KNOWN
        if known:  # B3
            e = p + buf[p + 2 - base] + MIN_FRAME
            if e == b:
                return self._emit(p, b, 0, crc_good=False)
            if not self._per_byte_at(p) and b < e <= end:
                at = self._is_boundary(e, end, final)
                if at is None:
                    return None
                if at and self._resync(b - 1, e, end, final) == e:
                    return self._emit(p, e, 0, crc_good=False)
        if (known and b - p >= MIN_FRAME and buf[p - base] <= MAX_UNIT  # B4
                and self._class_at(p) == HARD and self._is_hard(b, end, final)):
            return self._emit(p, b, 0, crc_good=False)
        return self._emit_noise(p, b)  # B5

    def _resync(self, p: int, b: int, end: int, final: bool):
        """B2: first q in (p, b) where a good frame (or a CRC-good run with a known header,
        ending plausibly) starts and its end is plausible; b if none."""
        for q in range(p + 1, b):
            hit = self._good_at(q, end, final, MAX_UNIT)
            if hit is _WAIT:
                return _WAIT
            if not hit:  # a frame whose LEN is off, ending where a frame may end
                cut = self._lenient_cut(q, b, end, final, strict=True)
                if cut is _WAIT:
                    return _WAIT
                if cut:
                    return q
                continue
            at = self._plausible_end(q + hit, end, final)
            if at is _WAIT:
                return _WAIT
            if at:
                return q
        return b

    def _plausible_end(self, e: int, end: int, final: bool):
        """After a frame ending at e: a boundary, a good frame, or a CRC-good run (lenient LEN)?"""
        at = self._is_boundary(e, end, final)
        if at is None:
            return _WAIT
        if at:
            return True
        nxt = self._good_at(e, end, final, MAX_UNIT)
        if nxt is _WAIT or nxt:
            return nxt
        b = self._next_boundary(e, end, final)
        if b is _WAIT:
            return _WAIT
        return self._lenient_cut(e, b, end, final, strict=True)

    # -------------------------------------------------------------- output
    def _emit(self, p: int, e: int, can: int = 0, crc_good: bool = True) -> Frame:
        raw = bytes(self.buf[p - self.base : e - self.base])
        fr = self._new_frame(p, e, self.protocol, raw)
        self._fill(fr, raw[:-2], crc_good)
        fr.crc_ok = crc_good
        if not crc_good:
            exp = crc_expected(raw)
            fr.crc_expected = exp
            fr.annotations.append(
                note(codes.CRC_MISMATCH,
                     f"CRC is 0x{crc_found(raw):04X}, expected 0x{exp:04X} (bytes {exp & 0xFF:02x} {exp >> 8:02x})",
                     len(raw) - 2, len(raw))
            )
        idle = fr.idle_before_ns
        if fr.time_source == "byte" and idle is not None and idle < QUIET_NS:
            fr.annotations.append(
                note(QUIET_SHORT, f"{idle / 1e6:.1f} ms of quiet before the frame (l.203-206: > 50 ms)", 0, 1)
            )
        self.pos = e
        return fr

    @staticmethod
    def _noise_reason(raw: bytes) -> str:
        if len(raw) < MIN_FRAME:
            return f"{len(raw)} byte(s): too short for a PD frame"
        if raw[1] not in KNOWN:
            return f"no frame: unknown function {raw[1]:02X}H and no valid CRC"
        return f"no frame: function {raw[1]:02X}H but LEN/CRC do not fit"


class PdAsciiFramer(_PdCommon, AsciiFramer):
    """':' ADDR FUNC LEN DATA LRC CR LF (l.64); cut like Modbus ASCII (AsciiFramer._step)."""

    protocol = "pd-ascii"
    codes = ASCII_CODES

    def _span(self, i: int, j: int) -> tuple[int, int]:
        return 1 + 2 * i, 1 + 2 * j

    def _emit_ascii(self, p: int, e: int, terminated: bool) -> Frame:
        raw = bytes(self.buf[p - self.base : e - self.base])
        text = raw[1:]
        tail = 2 if text.endswith(b"\r\n") else 1 if text.endswith((b"\r", b"\n")) else 0
        text = text[: len(text) - tail]
        try:
            binary = unhexlify(text) if len(text) % 2 == 0 else None
        except (HexError, ValueError):
            binary = None
        if binary is None or len(binary) < 3:
            # no unit or function can be read: a noise frame (sinks expect a unit on frames)
            fr = self._emit_noise(p, e)
            if binary is None:
                fr.annotations.append(note(BAD_HEX, "odd length or non-hex characters", 1, len(raw)))
            return fr
        adu, got = binary[:-1], binary[-1]
        fr = self._new_frame(p, e, self.protocol, raw)
        want = lrc(adu)
        fr.crc_ok = got == want
        self._fill(fr, adu, fr.crc_ok)
        if not fr.crc_ok:
            fr.crc_expected = want
            stop = len(raw) - tail
            fr.annotations.append(note(codes.CRC_MISMATCH, f"LRC is 0x{got:02X}, expected 0x{want:02X}",
                                       stop - 2, stop))
        if not (terminated and raw.endswith(b"\r\n")):
            fr.annotations.append(note(NO_CRLF, "frame ends without CR LF", len(raw) - 1, len(raw)))
        self.pos = e
        return fr

    @staticmethod
    def _noise_reason(raw: bytes) -> str:
        if not raw.startswith(b":"):
            return f"{len(raw)} byte(s) outside ':' ... CR LF"
        body = raw[1:].rstrip(b"\r\n")
        try:
            unhexlify(body)
        except (HexError, ValueError):
            return "':' frame whose characters are not hex pairs"
        return f"{len(body) // 2} byte(s) after ':': too short for ADDR FUNC + LRC"


__all__ = ["PdRtuFramer", "PdAsciiFramer", "FUNCTIONS", "ERRORS", "QUIET_NS", "roles"]
