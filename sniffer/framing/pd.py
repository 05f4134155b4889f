"""PD-series inverter framers: RTU (ADDR FUNC LEN DATA CRC-16) and ASCII (':' hex LRC CR LF).

The PD-series protocol (shared/manuals/pd-series-protocol.txt, "l.N" = line N)
only looks like Modbus.  Every frame is ADDR FUNC LEN DATA + check (l.64,
l.203); LEN counts the bytes between LEN and the check (our reading of l.181 /
l.107, see decoders/pd_series/NOTES.md), so the frame length is LEN + 5 in
RTU.  Sans-I/O and the same interface as RtuFramer / AsciiFramer: both are
LineBuffers; `PdHeader` reads the header for both, the RTU framer takes its
rule order from `Crc16Framing` and the ASCII framer its cutting from
`HexLineFraming`, not the Modbus rules.

RTU (`PdRtuFramer`, protocol "pd-rtu"):
  * the quiet time between frames is > 50 ms (l.203-206), not t3.5: it is the
    HARD silence for per-byte times (`hard_ns`); a frame never spans it.  A
    shorter silence (>= 1.5 characters, or a new USB read) is SOFT: a likely
    boundary that a frame may span.  The manual has no inter-character rule,
    so `modbus.timing.t15` is never emitted (t15_ns = the quiet time).
  * at each frame start, in this order (`Crc16Framing._step`), each rule a
    method named for it (`_rule_a_structural`, `_rule_b1_crc_run`, ...):
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
         malformed frame (bad CRC, `pd.len.mismatch` when LEN disagrees;
         `modbus.length.truncated` when LEN + 5 runs past it: cut off).
      B5. otherwise noise up to the boundary.
  * a byte the UART flagged is in no CRC-valid frame (`LineBuffer._flagged`):
    a 00 received with a framing error is never the CRC's high byte.
ASCII (`PdAsciiFramer`, protocol "pd-ascii"): ':' ... LF cut as in Modbus
ASCII (`HexLineFraming`); `raw` keeps the characters, `adu` the binary
ADDR..DATA without the LRC.  The LRC is the manual's (l.187): 100H minus the
byte sum of ADDR..DATA, mod 256.

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

from fastcrc.crc16 import modbus as crc16_modbus  # incremental: `initial` = the running register

from sniffer.codes import CRC_MISMATCH, CRC_ONE_BYTE, ERROR, INFO, LENGTH_TRUNCATED, LINE_CODES, WARNING, Code, note
from sniffer.framing.crc import crc_ok
from sniffer.framing.crc_rules import NEXT, Crc16Framing
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.framing.hexline import HexLineFraming
from sniffer.framing.linebuf import WAIT, LineBuffer

QUIET_NS = 50_000_000  # l.203-206: "the time of no data is more than 50 ms"
MIN_FRAME = 5  # ADDR FUNC LEN + CRC (LEN = 0)
MAX_UNIT = 250  # l.73: 01~250 inverters, 00 broadcast
# Function codes only, for framing; decoders/pd_series/schema.py describes each one
# (tests/test_pd_series.py checks that both name the same codes).
FUNCTIONS = frozenset({0x01, 0x02, 0x03, 0x04, 0x05, 0x08})  # l.77-91
RESERVED = frozenset({0x06, 0x07})  # l.87-89
ERRORS = frozenset({0x81, 0x83})  # error replies (l.111, l.125, l.153)
KNOWN = FUNCTIONS | ERRORS

# The PD-series framers' own codes, declared beside them (each framer's `codes` claims its own; the code book
# gathers them through sniffer.protocols)
LEN_MISMATCH = Code("pd.len.mismatch", WARNING, "LEN does not count the frame's data bytes")
QUIET_SHORT = Code("pd.timing.quiet", INFO, "less than the manual's 50 ms of quiet before the frame")
FUNCTION_UNKNOWN = Code("pd.function.unknown", WARNING, "function code not defined by the PD-series protocol")
WRITE_ERROR = Code("pd.error.write", INFO, "81H error reply to a write parameter (02H): paired as 82H")
NO_CRLF = Code("pd.ascii.no_crlf", WARNING, "ASCII frame not ended by CR LF")
BAD_HEX = Code("pd.ascii.bad_hex", ERROR, "ASCII frame holds characters that are not hex digits")
RTU_CODES = LINE_CODES + (CRC_MISMATCH, CRC_ONE_BYTE, LEN_MISMATCH, QUIET_SHORT, FUNCTION_UNKNOWN, WRITE_ERROR,
                          LENGTH_TRUNCATED)
ASCII_CODES = LINE_CODES + (CRC_MISMATCH, LEN_MISMATCH, FUNCTION_UNKNOWN, WRITE_ERROR, NO_CRLF, BAD_HEX)


def roles(unit: int, fc: int) -> int:
    """CAN_REQ/CAN_RSP from the header: requests and replies share one layout."""
    if fc & 0x80:
        return CAN_RSP
    if unit == 0:
        return CAN_REQ
    return CAN_REQ | CAN_RSP


class PdHeader:
    """Mixin for both PD framers: the quiet time, the header (unit, function, roles), the LEN check,
    the 81H pairing key."""

    def __init__(self, line, *, read_slack_ns: int = 50_000_000) -> None:
        super().__init__(line, read_slack_ns=read_slack_ns)
        self.hard_ns = QUIET_NS
        self.t15_ns = QUIET_NS  # no inter-character rule in the manual
        self._last: tuple[int, int] | None = None  # (unit, wire function) of the last frame

    def _span(self, i: int, j: int) -> tuple[int, int]:
        """Byte span of ADU bytes [i, j) inside raw (identity for RTU)."""
        return i, j

    def _header(self, fr: Frame, adu: bytes, crc_good: bool) -> None:
        unit, fc = adu[0], adu[1]
        fr.unit, fr.function, fr.adu = unit, fc, adu
        fr.role_fits = roles(unit, fc)
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


class PdRtuFramer(PdHeader, Crc16Framing, LineBuffer):
    protocol = "pd-rtu"
    codes = RTU_CODES

    # --------------------------------------------------------------- rules
    def _rule_a_structural(self, p: int, end: int, final: bool):
        """A: LEN + 5 bytes with a good CRC and a known function (`_settle_zero_end` for a 00 end)."""
        hit = self._good_at(p, end, final)
        if hit is WAIT:
            return WAIT
        if not hit:
            return NEXT
        e = self._settle_zero_end(p, p + hit, end, final)
        if e is WAIT:
            return WAIT
        return self._emit(p, e, 0, crc_good=True)

    def _rule_b1_crc_run(self, p: int, b: int, end: int, final: bool):
        """B1, lenient LEN: the shortest CRC-good run that ends plausibly (`_lenient_cut`)."""
        e = self._lenient_cut(p, b, end, final)
        if e is WAIT:
            return WAIT
        if e:
            return self._emit(p, e, 0, crc_good=True)
        return NEXT

    def _rule_b3_damaged_frame(self, p: int, b: int, end: int, final: bool):
        """B3: LEN + 5 ends exactly at the boundary (or, per read, at a later read boundary): bad CRC."""
        buf, base = self.buf, self.base
        if not (b - p >= 3 and buf[p + 1 - base] in KNOWN):
            return NEXT
        e = p + buf[p + 2 - base] + MIN_FRAME
        if e == b:
            return self._emit(p, b, 0, crc_good=False)
        if not self._per_byte_at(p):
            at = self._damaged_ends_at(e, b, end, final)
            if at is WAIT:
                return WAIT
            if at:
                return self._emit(p, e, 0, crc_good=False)
        return NEXT

    def _rule_b4_malformed_burst(self, p: int, b: int, end: int, final: bool):
        """B4: a whole burst between two quiets, known function and unit: malformed (bad CRC, LEN noted)."""
        buf, base = self.buf, self.base
        if (b - p >= MIN_FRAME and buf[p + 1 - base] in KNOWN and buf[p - base] <= MAX_UNIT
                and self._whole_burst(p, b, end, final)):
            fr = self._emit(p, b, 0, crc_good=False)
            want, n = buf[p + 2 - base] + MIN_FRAME, b - p
            if want > n:  # the frame LEN announces, cut off
                fr.annotations.append(note(LENGTH_TRUNCATED, f"cut off: {n} of the {want} bytes LEN announces "
                                                             f"({want - n} missing)", 0, n))
            return fr
        return NEXT

    def _frame_starts_at(self, q: int, b: int, end: int, final: bool):
        """B2's test at q: a good frame (or a CRC-good run with a known header, ending plausibly)
        whose end is plausible."""
        hit = self._good_at(q, end, final, MAX_UNIT)
        if hit is WAIT:
            return WAIT
        if not hit:  # a frame whose LEN is off, ending where a frame may end
            cut = self._lenient_cut(q, b, end, final, strict=True)
            return WAIT if cut is WAIT else bool(cut)
        at = self._plausible_end(q + hit, end, final)
        return WAIT if at is WAIT else bool(at)

    # ------------------------------------------------------------- helpers
    def _good_at(self, q: int, end: int, final: bool, max_unit: int = 255):
        """Length of a LEN-consistent, CRC-good frame of a known function at q; False; or WAIT."""
        buf, base = self.buf, self.base
        if buf[q - base] > max_unit or (q + 1 < end and buf[q + 1 - base] not in KNOWN):
            return False
        if q + 2 >= end:
            return False if final else WAIT
        n = buf[q + 2 - base] + MIN_FRAME
        if q + n > end:
            return False if final else WAIT
        return n if crc_ok(buf[q - base : q + n - base]) and not self._flagged(q, q + n) else False

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
        if at is WAIT:
            return WAIT
        if at:
            return e
        short = self._plausible_end(e - 1, end, final)
        if short is WAIT:
            return WAIT
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
                if self._flagged(p, c):  # a flagged byte is in no CRC-valid frame
                    continue
                if c == b or not any(buf[c - base : b - base]):
                    return c
                nxt = self._good_at(c, end, final, MAX_UNIT)
                if nxt is False:
                    nxt = self._lenient_cut(c, b, end, final, strict=True)
                if nxt is WAIT:
                    return WAIT
                if nxt:
                    return c
        return False

    def _plausible_end(self, e: int, end: int, final: bool):
        """After a frame ending at e: a boundary, a good frame, or a CRC-good run (lenient LEN)?"""
        at = self._is_boundary(e, end, final)
        if at is None:
            return WAIT
        if at:
            return True
        nxt = self._good_at(e, end, final, MAX_UNIT)
        if nxt is WAIT or nxt:
            return nxt
        b = self._next_boundary(e, end, final)
        if b is WAIT:
            return WAIT
        return self._lenient_cut(e, b, end, final, strict=True)

    # -------------------------------------------------------------- output
    def _short_silence_note(self, idle_ns: int):
        return note(QUIET_SHORT, f"{idle_ns / 1e6:.1f} ms of quiet before the frame (l.203-206: > 50 ms)", 0, 1)

    def noise_reason(self, raw: bytes) -> str:
        if len(raw) < MIN_FRAME:
            return f"{len(raw)} byte(s): too short for a PD frame"
        if raw[1] not in KNOWN:
            return f"no frame: unknown function {raw[1]:02X}H and no valid CRC"
        return f"no frame: function {raw[1]:02X}H but LEN/CRC do not fit"


class PdAsciiFramer(PdHeader, HexLineFraming, LineBuffer):
    """':' ADDR FUNC LEN DATA LRC CR LF (l.64); cut like Modbus ASCII (`HexLineFraming`)."""

    protocol = "pd-ascii"
    codes = ASCII_CODES
    no_crlf_code = NO_CRLF
    bad_hex_code = BAD_HEX
    header_words = "ADDR FUNC + LRC"

    def _span(self, i: int, j: int) -> tuple[int, int]:
        return 1 + 2 * i, 1 + 2 * j


__all__ = ["PdRtuFramer", "PdAsciiFramer", "FUNCTIONS", "ERRORS", "QUIET_NS", "roles"]
