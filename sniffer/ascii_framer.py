"""Modbus ASCII framer: ':' + hex pairs + LRC + CR LF (Modbus serial line spec 2.5.2).

Sans-I/O, same interface as RtuFramer (it reuses its buffer, timestamps and
silences).  `Frame.raw` holds the wire characters (so every byte is kept),
`Frame.adu` the decoded binary unit + PDU without the LRC, which is what the
decoders read; the decoders' byte spans are mapped back onto the characters
by the registry.  A bad LRC is flagged like a bad CRC (`modbus.crc.mismatch`,
with the expected LRC).  Bytes outside ':' ... LF are noise.
"""

from __future__ import annotations

from binascii import Error as HexError
from binascii import unhexlify

from . import codes
from .codes import ASCII_BAD_HEX as BAD_HEX
from .codes import ASCII_NO_CRLF as NO_CRLF
from .codes import RTU_CODES, note
from .crc import lrc
from .frame import CAN_REQ, CAN_RSP, Frame
from .framer import RtuFramer, _WAIT
from .rtu_layout import Need, candidates

MAX_ASCII = 1 + 2 * 256 + 2  # ':' + 2 * (ADU + LRC) + CR LF


class AsciiFramer(RtuFramer):
    protocol = "modbus-ascii"
    codes = RTU_CODES + (NO_CRLF, BAD_HEX)

    def _step(self, p: int):
        base = self.base
        buf = self.buf
        end = base + len(buf)
        if p >= end:
            return None
        final = self.closed
        if buf[p - base] != 0x3A:  # ':'
            q = buf.find(b":", p - base)
            if q < 0:
                if not final and end - p < MAX_ASCII:
                    return _WAIT
                return self._emit_noise(p, end if end - p < MAX_ASCII else p + MAX_ASCII)
            return self._emit_noise(p, base + q)
        nl = buf.find(b"\n", p + 1 - base)
        colon = buf.find(b":", p + 1 - base)
        if colon >= 0 and (nl < 0 or colon < nl):
            return self._emit_ascii(p, base + colon, terminated=False)
        if nl < 0:
            if not final and end - p < MAX_ASCII:
                return _WAIT
            return self._emit_ascii(p, min(end, p + MAX_ASCII), terminated=False)
        return self._emit_ascii(p, base + nl + 1, terminated=True)

    def _emit_ascii(self, p: int, e: int, terminated: bool) -> Frame:
        raw = bytes(self.buf[p - self.base : e - self.base])
        text = raw[1:]
        if text.endswith(b"\r\n"):
            text = text[:-2]
        elif text.endswith(b"\n") or text.endswith(b"\r"):
            text = text[:-1]
        try:
            binary = unhexlify(text) if len(text) % 2 == 0 else None
        except (HexError, ValueError):
            binary = None
        if binary is None or len(binary) < 3:
            if len(raw) < 7:
                return self._emit_noise(p, e)
            fr = self._new_frame(p, e, self.protocol, raw)
            fr.crc_ok = False
            fr.annotations.append(note(BAD_HEX, "odd length or non-hex characters", 1, len(raw)))
            self.pos = e
            return fr
        adu, got = binary[:-1], binary[-1]
        fr = self._new_frame(p, e, self.protocol, raw)
        fr.unit, fr.function, fr.adu = adu[0], adu[1], adu
        fr.can = _roles(adu)
        want = lrc(adu)
        fr.crc_ok = got == want
        if not fr.crc_ok:
            fr.crc_expected = want
            fr.annotations.append(
                note(codes.CRC_MISMATCH, f"LRC is 0x{got:02X}, expected 0x{want:02X}", len(raw) - 4, len(raw) - 2)
            )
        if not (terminated and raw.endswith(b"\r\n")):
            fr.annotations.append(note(NO_CRLF, "frame ends without CR LF", len(raw) - 1, len(raw)))
        self.pos = e
        return fr


def _roles(adu: bytes) -> int:
    """Which roles the ADU's length fits, from the RTU length rules (CRC bytes stand in for LRC)."""
    rtu = adu + b"\0\0"
    can = 0
    for length, bits in candidates(rtu, 0, len(rtu)):
        if type(length) is not Need and length == len(rtu):
            can |= bits
    return can or (CAN_REQ | CAN_RSP)
