"""What the binary framers share: rules A, B1..B5 in order, over a line of CRC-16 checked frames.

`Crc16Framing` is a mixin for a `LineBuffer` subclass whose frames end in a
CRC-16/MODBUS (Modbus RTU, PD-series RTU).  At each frame start `_step`
tries the framer's rules in this order, each a method of that name:

  A   `_rule_a_structural`          the length the header implies, good CRC;
  B1  `_rule_b1_crc_run`            a CRC-good run the header does not explain;
  B2  `_rule_b2_noise_before_frame` a good frame starts later: noise before it;
  B3  `_rule_b3_damaged_frame`      the header's length ends at a boundary, bad CRC;
  B3b `_rule_b3b_frame_inside`      a good frame inside the run, junk on both sides;
  B3c `_rule_b3c_crc_pieces`        (RTU) the run splits into CRC-valid pieces;
  B4  `_rule_b4_malformed_burst`    a whole burst between two HARD silences;
  B5  `_rule_b5_noise`              noise up to the next boundary.

A rule returns a Frame (decided), `NEXT` (the rule does not apply: try the
next one) or `WAIT` (the decision needs bytes not here yet).  A framer
supplies A, B1, B3, B4 (B3b if it has one), `_frame_starts_at` (for B2's scan), `_header` (unit,
function, adu and header notes of an emitted frame) and `_short_silence_note`;
B2, B5, the scan and the emission live here.

A CRC that holds over a byte the UART flagged is no proof (`LineBuffer._flagged`):
the framers' CRC checks skip such a span, and a frame that holds one anyway
is emitted damaged (`modbus.crc.unproven`).  `_last_good` keeps what the
framer last emitted (the evidence of what is pending, for a framer that
weighs two CRC-valid readings of one header).
"""

from __future__ import annotations

from sniffer import codes
from sniffer.codes import Annotation, note
from sniffer.framing.crc import crc_expected, crc_found, damaged_byte
from sniffer.frame import Frame
from sniffer.framing.linebuf import WAIT, HARD

NEXT = False  # a rule's "does not apply here": distinct from WAIT (None)


class Crc16Framing:
    """Mixin for LineBuffer subclasses: the rule order, B2/B5, the later-frame scan, CRC-16 frame emission."""

    # (roles, raw) of the last frame emitted with a good CRC; None before the first and after a
    # damaged one (nothing reliable is pending).  Noise leaves it as it is.
    _last_good: tuple[int, bytes] | None = None

    # ------------------------------------------------------------ the order
    def _step(self, p: int):
        """The frame that starts at p, or None while the decision waits for bytes."""
        end, final = self._avail(p)
        if p >= end:
            return None
        fr = self._rule_a_structural(p, end, final)
        if fr is not NEXT:
            return fr
        b = self._next_boundary(p, end, final)
        if b is WAIT:
            return None
        for rule in (self._rule_b1_crc_run, self._rule_b2_noise_before_frame,
                     self._rule_b3_damaged_frame, self._rule_b3b_frame_inside, self._rule_b4_malformed_burst):
            fr = rule(p, b, end, final)
            if fr is not NEXT:
                return fr
        return self._rule_b5_noise(p, b)

    def _rule_a_structural(self, p: int, end: int, final: bool):  # pragma: no cover - each framer's own
        raise NotImplementedError

    def _rule_b1_crc_run(self, p: int, b: int, end: int, final: bool):  # pragma: no cover
        raise NotImplementedError

    def _rule_b2_noise_before_frame(self, p: int, b: int, end: int, final: bool):
        """B2: a good frame starts after p, before the boundary b, and ends plausibly: [p, q) is noise
        (noise glued to a frame in one read or burst)."""
        q = self._resync(p, b, end, final)
        if q is WAIT:
            return WAIT
        if q < b:
            return self._emit_noise(p, q)
        return NEXT

    def _rule_b3_damaged_frame(self, p: int, b: int, end: int, final: bool):  # pragma: no cover
        raise NotImplementedError

    def _rule_b3b_frame_inside(self, p: int, b: int, end: int, final: bool):
        """B3b: a good frame inside [p, b) with junk on both sides (a framer may add it; not by default)."""
        return NEXT

    def _rule_b4_malformed_burst(self, p: int, b: int, end: int, final: bool):  # pragma: no cover
        raise NotImplementedError

    def _rule_b5_noise(self, p: int, b: int) -> Frame:
        """B5: nothing else fits: noise up to the boundary."""
        return self._emit_noise(p, b)

    # ------------------------------------------------------- shared scans
    def _frame_starts_at(self, q: int, b: int, end: int, final: bool):  # pragma: no cover
        """True if a good frame starts at q and ends plausibly; False; or WAIT (each framer's own)."""
        raise NotImplementedError

    def _resync(self, p: int, b: int, end: int, final: bool):
        """The first q in (p, b) where `_frame_starts_at` holds; b if none; WAIT while unknown."""
        starts = self._frame_starts_at
        for q in range(p + 1, b):
            at = starts(q, b, end, final)
            if at is WAIT:
                return WAIT
            if at:
                return q
        return b

    def _damaged_ends_at(self, e: int, b: int, end: int, final: bool):
        """B3 with per-read times: a damaged frame that runs past the read boundary b ends at e?

        An adapter splits a damaged frame across reads as readily as a good
        one: [p, e) is taken if e is a boundary too (a later read's end, or the
        end of data) and no good frame starts between b - 1 and e.  True,
        False, or WAIT while e's boundary is unknown.
        """
        if not b < e <= end:
            return False
        at = self._is_boundary(e, end, final)
        if at is None:
            return WAIT
        return bool(at) and self._resync(b - 1, e, end, final) == e

    def _whole_burst(self, p: int, b: int, end: int, final: bool) -> bool:
        """B4's condition: [p, b) lies between two HARD silences (the Modbus definition of a frame)."""
        return self._class_at(p) == HARD and self._is_hard(b, end, final)

    # -------------------------------------------------------------- output
    def _header(self, fr: Frame, adu: bytes, crc_good: bool) -> None:  # pragma: no cover
        """Unit, function, adu and header annotations of an emitted frame (each framer's own; `fr.role_fits`
        holds the roles the rule found, which the header may narrow)."""
        raise NotImplementedError

    def _short_silence_note(self, idle_ns: int) -> Annotation:  # pragma: no cover
        """The annotation for a frame that started less than `hard_ns` after the previous one."""
        raise NotImplementedError

    def _emit(self, p: int, e: int, can: int, crc_good: bool, raw: bytes | None = None) -> Frame:
        """Bytes [p, e) as a frame: header, CRC verdict (the expected CRC when bad), silence before it."""
        if raw is None:
            raw = bytes(self.buf[p - self.base : e - self.base])
        fr = self._new_frame(p, e, self.protocol, raw)
        fr.role_fits = can
        self._header(fr, raw[:-2], crc_good)
        fr.crc_ok = crc_good
        if not crc_good:
            exp = crc_expected(raw)
            if crc_found(raw) == exp and self._flagged(p, e):
                fr.annotations.append(self._unproven_note(p, e, "CRC", len(raw) - 2, len(raw)))
            else:
                fr.crc_expected = exp
                fr.annotations.append(
                    note(codes.CRC_MISMATCH,
                         f"CRC is 0x{crc_found(raw):04X}, expected 0x{exp:04X} (bytes {exp & 0xFF:02x} {exp >> 8:02x})",
                         len(raw) - 2, len(raw))
                )
                hit = damaged_byte(raw)
                if hit is not None:  # which byte broke it, where one byte of the line-fault kind explains it
                    at, was = hit
                    what = ("the address" if at == 0 else "the CRC's low byte" if at == len(raw) - 2
                            else "the last byte")
                    fr.annotations.append(note(codes.CRC_ONE_BYTE, f"the CRC holds with byte {at} ({what}) = "
                                               f"0x{was:02X} instead of 0x{raw[at]:02X}", at, at + 1))
        self._last_good = (fr.role_fits, raw) if crc_good else None
        idle = fr.idle_before_ns
        if fr.time_source == "byte" and idle is not None and idle < self.hard_ns:
            fr.annotations.append(self._short_silence_note(idle))
        self.pos = e
        return fr
