"""':' hex-pairs CR LF framing: what the Modbus ASCII and PD-series ASCII framers share.

`HexLineFraming` is a mixin for a `LineBuffer` subclass.  Cutting (`_step`),
on characters only (silences play no part):
  * a character other than ':' starts noise, up to the next ':';
  * ':' starts a frame, up to and including the next LF; when another ':'
    comes first the frame ends before it (no CR LF);
  * nothing is longer than MAX_LINE characters: a run without its ':' or LF
    within that many is cut there, so how reads were cut never matters.
Reading a frame (`_emit_line`): the characters between ':' and CR LF must be
hex pairs holding at least unit, function and the LRC; otherwise the line is
a noise frame that says why in ASCII terms (and carries the framer's
`bad_hex_code` when the characters are not hex pairs).  A bad LRC is flagged
like a bad CRC (`modbus.crc.mismatch` over the LRC characters, the expected
value in `crc_expected`); a frame not ended by CR LF gets `no_crlf_code`.  A
line holding a character the UART flagged is never LRC-valid (an 8-bit LRC
proves little, and nothing over a character received wrong):
`modbus.crc.unproven` when the LRC matches all the same.
A framer supplies `_header(fr, adu, crc_good)` (unit, function, adu, roles
and header notes) and the two codes.
"""

from __future__ import annotations

from binascii import Error as HexError
from binascii import unhexlify

from sniffer import codes
from sniffer.codes import Code, note
from sniffer.framing.crc import lrc
from sniffer.frame import Frame
from sniffer.framing.linebuf import WAIT

MAX_LINE = 1 + 2 * 256 + 2  # ':' + 2 * (ADU + LRC) + CR LF
_HEX = frozenset(b"0123456789abcdefABCDEF")


class HexLineFraming:
    """Mixin for LineBuffer subclasses: ':' ... LF cutting, hex pairs, LRC verdict, noise in ASCII words."""

    no_crlf_code: Code
    bad_hex_code: Code
    header_words = "unit, function and LRC"  # what a too-short line lacks, in the protocol's words

    def _step(self, p: int):
        base, buf = self.base, self.buf
        end = base + len(buf)
        if p >= end:
            return None
        final = self.closed
        i = p - base
        stop = i + MAX_LINE  # nothing spans more characters than this
        if buf[i] != 0x3A:  # ':'
            q = buf.find(b":", i, stop)
            if q >= 0:
                return self._emit_noise(p, base + q)
            if not final and end - p < MAX_LINE:
                return WAIT
            return self._emit_noise(p, min(end, p + MAX_LINE))
        nl = buf.find(b"\n", i + 1, stop)
        colon = buf.find(b":", i + 1, stop)
        if colon >= 0 and (nl < 0 or colon < nl):
            return self._emit_line(p, base + colon, terminated=False)
        if nl >= 0:
            return self._emit_line(p, base + nl + 1, terminated=True)
        if not final and end - p < MAX_LINE:
            return WAIT
        return self._emit_line(p, min(end, p + MAX_LINE), terminated=False)

    def _emit_line(self, p: int, e: int, terminated: bool) -> Frame:
        raw = bytes(self.buf[p - self.base : e - self.base])
        tail = _tail(raw)
        binary = _hex_pairs(raw[1 : len(raw) - tail])
        if binary is None or len(binary) < 3:
            fr = self._emit_noise(p, e)
            if binary is None:
                fr.annotations.append(note(self.bad_hex_code, *_hex_problem(raw, tail)))
            return fr
        adu, got = binary[:-1], binary[-1]
        fr = self._new_frame(p, e, self.protocol, raw)
        want = lrc(adu)
        unproven = got == want and self._flagged(p, e)  # an LRC over a flagged character proves nothing
        fr.crc_ok = got == want and not unproven
        self._header(fr, adu, fr.crc_ok)
        if unproven:
            stop = len(raw) - tail
            fr.annotations.append(self._unproven_note(p, e, "LRC", stop - 2, stop))
        elif not fr.crc_ok:
            fr.crc_expected = want
            stop = len(raw) - tail
            fr.annotations.append(
                note(codes.CRC_MISMATCH, f"LRC is 0x{got:02X}, expected 0x{want:02X}", stop - 2, stop)
            )
        if not (terminated and raw.endswith(b"\r\n")):
            fr.annotations.append(note(self.no_crlf_code, "frame ends without CR LF", len(raw) - 1, len(raw)))
        self.pos = e
        return fr

    def noise_reason(self, raw: bytes) -> str:
        if not raw.startswith(b":"):
            return f"{len(raw)} character(s) outside ':' ... CR LF"
        tail = _tail(raw)
        binary = _hex_pairs(raw[1 : len(raw) - tail])
        if binary is None:
            return f"':' frame whose characters are not hex pairs ({_hex_problem(raw, tail)[0]})"
        return f"{len(binary)} byte(s) after ':': too short for {self.header_words}"


def _tail(raw: bytes) -> int:
    """How many line-end characters (CR LF, or a lone CR or LF) close the line."""
    if raw.endswith(b"\r\n") and len(raw) >= 3:
        return 2
    return 1 if len(raw) >= 2 and raw.endswith((b"\r", b"\n")) else 0


def _hex_pairs(text: bytes) -> bytes | None:
    if len(text) % 2:
        return None
    try:
        return unhexlify(text)
    except (HexError, ValueError):
        return None


def _hex_problem(raw: bytes, tail: int) -> tuple[str, int, int]:
    """What keeps a line's characters from being hex pairs, and its span in `raw` (the first
    non-hex character, or all the digits when their number is odd)."""
    stop = len(raw) - tail
    for k in range(1, stop):
        if raw[k] not in _HEX:
            return f"{chr(raw[k])!r} at character {k} is not a hex digit", k, k + 1
    return f"an odd number ({stop - 1}) of hex digits", 1, stop
