"""Modbus ASCII framer: ':' + hex pairs + LRC + CR LF (Modbus serial line spec 2.5.2).

Sans-I/O, same interface as RtuFramer (the LineBuffer's).  Cutting and
reading the line are `HexLineFraming`'s (sniffer/framing/hexline.py): `Frame.raw`
holds the wire characters (so every byte is kept), `Frame.adu` the decoded
binary unit + PDU without the LRC, which is what the decoders read; the
decoders' byte spans are mapped back onto the characters by the registry.
A bad LRC is flagged like a bad CRC (`modbus.crc.mismatch`, with the
expected LRC).  Characters outside ':' ... LF are noise, and so is a ':'
line whose characters are not hex pairs (`modbus.ascii.bad_hex` says so) or
too short for unit, function and LRC: a frame always has a unit and a
function, so the pairer never sees an ASCII frame it cannot read.
"""

from __future__ import annotations

from sniffer.codes import (
    ASCII_BAD_HEX, ASCII_NO_CRLF, CRC_MISMATCH, FUNCTION_UNKNOWN, FUNCTION_USER, LENGTH_MISMATCH, LINE_CODES,
    STRUCTURE_MISMATCH, UNIT_RESERVED, note,
)
from sniffer.frame import CAN_REQ, CAN_RSP, Frame
from sniffer.framing.hexline import HexLineFraming
from sniffer.framing.linebuf import LineBuffer
from sniffer.framing.rtu_lengths import KNOWN_FUNCTIONS, Need, candidates, roles


class AsciiFramer(HexLineFraming, LineBuffer):
    protocol = "modbus-ascii"
    codes = LINE_CODES + (CRC_MISMATCH, ASCII_NO_CRLF, ASCII_BAD_HEX, UNIT_RESERVED, STRUCTURE_MISMATCH,
                          LENGTH_MISMATCH, FUNCTION_UNKNOWN, FUNCTION_USER)
    no_crlf_code = ASCII_NO_CRLF
    bad_hex_code = ASCII_BAD_HEX

    def _header(self, fr: Frame, adu: bytes, crc_good: bool) -> None:
        fr.unit, fr.function, fr.adu = adu[0], adu[1], adu
        fits = _roles(adu)
        fr.role_fits, why = roles(adu, fits or (CAN_REQ | CAN_RSP))
        if not fits:  # as RTU's rule B1 says it: the LRC (not a length) made it a frame
            fc = adu[1]
            if (fc & 0x7F) in KNOWN_FUNCTIONS and fc != 0x80:
                fr.annotations.append(note(LENGTH_MISMATCH, f"{len(adu)} bytes (without LRC) do not fit function "
                                                            f"0x{fc:02X}", 1, 1 + 2 * len(adu)))
            else:
                user = 65 <= (fc & 0x7F) <= 72 or 100 <= (fc & 0x7F) <= 110
                fr.annotations.append(note(FUNCTION_USER if user else FUNCTION_UNKNOWN,
                                           f"function 0x{fc:02X} ({fc}) shown raw", 3, 5))
        if adu[0] > 247:  # a framer's spans are in characters: ADU byte i is characters 1 + 2i, 2 + 2i
            fr.annotations.append(note(UNIT_RESERVED, f"unit {adu[0]} (248-255 are reserved)", 1, 3))
        if why:
            fr.annotations.append(note(STRUCTURE_MISMATCH, why, 5, 1 + 2 * len(adu)))


def _roles(adu: bytes) -> int:
    """Which roles the ADU's length fits, from the RTU length rules (CRC bytes stand in for LRC); 0: none."""
    rtu = adu + b"\0\0"
    can = 0
    for length, bits in candidates(rtu, 0, len(rtu)):
        if type(length) is not Need and length == len(rtu):
            can |= bits
    return can


__all__ = ["AsciiFramer"]
