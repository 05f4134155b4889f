"""PacketFramer: the framing of a protocol whose frame says its own length and ends in a check, for plugins.

A vendor protocol (a start byte, an address, a length byte, data, its own CRC) is a subclass that says
four things, all public; the line's silences, byte times, UART flags, noise and the frame records are
LineBuffer's, as for every built-in framer:

    class AcmeFramer(PacketFramer):
        protocol = "acme"                       # the ProtocolPlugin's name
        head_size = 4                           # bytes that tell the length
        def frame_length(self, head): ...       # the whole frame's length from them, or None: no frame starts here
        def check(self, raw): ...               # (the check holds, the value it should have had or None)
        def describe(self, frame): ...          # frame.unit, .function, .role_fits (CAN_REQ / CAN_RSP), .adu

At each frame start, in this order:
  * a head that starts no frame (or too few bytes before a silence): noise, up to the first later byte where a
    whole frame with a good check starts, else up to the next silence (HARD or SOFT boundary);
  * a frame that would run past a silence that proved the line quiet: cut there (`modbus.length.truncated`),
    unless a good frame starts inside it (then the bytes before that are noise);
  * a frame whose check fails: noise up to a good frame inside it if there is one (a damaged length or start
    byte), else the frame, `modbus.crc.mismatch` (as the built-in framings say it, so `crc` filters and the
    figures count it);
  * otherwise the frame; a check that holds over a byte the UART flagged is no proof: `modbus.crc.unproven`.
"""

from __future__ import annotations

from sniffer.codes import CRC_MISMATCH, CRC_UNPROVEN, LENGTH_TRUNCATED, LINE_CODES, note
from sniffer.frame import Frame
from sniffer.framing.linebuf import WAIT, LineBuffer
from sniffer.framing.rtu_lengths import MAX_ADU

PACKET_CODES = LINE_CODES + (CRC_MISMATCH, CRC_UNPROVEN, LENGTH_TRUNCATED)
PENDING = "pending"  # a search's answer while bytes it needs may still come (WAIT is None: "none found" too)


class PacketFramer(LineBuffer):
    protocol = "packet"
    codes = PACKET_CODES
    head_size = 1
    max_length = MAX_ADU + 8

    def frame_length(self, head: bytes) -> int | None:  # pragma: no cover - each protocol says it
        """The whole frame's length (head included) from its first `head_size` bytes; None: no frame here."""
        raise NotImplementedError

    def check(self, raw: bytes) -> tuple[bool, int | None]:  # pragma: no cover - each protocol says it
        """(the frame's check holds, the value it should have had, or None)."""
        raise NotImplementedError

    def describe(self, frame: Frame) -> None:
        """Set what the pairer and the decoder read: unit, function, role_fits, adu (default: the raw bytes)."""
        frame.adu = frame.raw

    def _good_at(self, q: int, end: int, final: bool):
        """Does a whole frame with a good check start at q: True, False, or PENDING (its end is still to come)."""
        base, n = self.base, self.head_size
        if end - q < n:
            return PENDING if not final else False
        length = self.frame_length(bytes(self.buf[q - base:q - base + n]))
        if length is None or not n <= length <= self.max_length:
            return False
        if q + length > end:
            if final:
                return False
            self._need = q + length
            return PENDING
        return self.check(bytes(self.buf[q - base:q + length - base]))[0] and not self._flagged(q, q + length)

    def _resync(self, p: int, stop: int, end: int, final: bool):
        """The first q in (p, stop) where a good frame starts (the bytes before it are noise), None if none does,
        or PENDING while one may still arrive."""
        for q in range(p + 1, stop):
            good = self._good_at(q, end, final)
            if good is PENDING:
                return PENDING
            if good:
                return q
        return None

    def _step(self, p: int):
        end, final = self._avail(p)
        if p >= end:
            return WAIT
        base, n = self.base, self.head_size
        length = self.frame_length(bytes(self.buf[p - base:p - base + n])) if end - p >= n else None
        if end - p < n and not final:
            self._need = p + n
            return WAIT
        if length is None or not n <= length <= self.max_length:
            # no frame starts here: noise up to a good frame, else up to the next silence
            q = self._next_boundary(p, end, final)
            good = self._resync(p, end if q is WAIT else q, end, final)
            if good is PENDING or (good is None and q is WAIT):
                return WAIT
            return self._emit_noise(p, q if good is None else good)
        e = p + length
        cut = e > end
        if cut and not final:
            self._need = e
            return WAIT
        e = min(e, end)
        raw = bytes(self.buf[p - base:e - base])
        ok, expected = (False, None) if cut else self.check(raw)
        if not ok:  # a damaged length or start: a good frame inside it wins, the bytes before it are noise
            good = self._resync(p, e, end, final)
            if good is PENDING:
                return WAIT
            if good is not None:
                return self._emit_noise(p, good)
        fr = self._new_frame(p, e, self.protocol, raw)
        if cut:
            fr.annotations.append(note(LENGTH_TRUNCATED, f"{len(raw)} of the {length} bytes its header announces",
                                       0, len(raw)))
        elif ok and self._flagged(p, e):
            ok = False
            fr.annotations.append(self._unproven_note(p, e, "the check", 0, len(raw)))
        elif not ok:
            fr.annotations.append(note(CRC_MISMATCH, "the frame's check does not hold"
                                       + (f" (expected {expected:#x})" if expected is not None else ""), 0, len(raw)))
        fr.crc_ok, fr.crc_expected = ok, expected
        self.describe(fr)
        self.pos = e
        return fr
