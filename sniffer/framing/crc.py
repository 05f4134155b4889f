"""CRC-16/MODBUS and LRC, outside construct (construct's Checksum raises and is slow)."""

from __future__ import annotations

from fastcrc import crc16

crc16_raw = crc16.modbus


def crc16_modbus(data: bytes) -> int:
    """CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF) of `data`."""
    return crc16_raw(data)


def crc_ok(frame: bytes) -> bool:
    """True if the last two bytes of `frame` are its CRC (low byte first).

    Checking the residual of the whole frame is equivalent and one call.
    """
    return crc16_raw(frame) == 0


def crc_found(frame: bytes) -> int:
    """The CRC value carried by the frame's last two bytes."""
    return frame[-2] | (frame[-1] << 8)


def crc_expected(frame: bytes) -> int:
    """The CRC the frame's payload should carry."""
    return crc16_raw(frame[:-2])


def crc_bytes(payload: bytes) -> bytes:
    """The two CRC bytes to append to `payload`."""
    c = crc16_raw(payload)
    return bytes((c & 0xFF, c >> 8))


def lrc(data: bytes) -> int:
    """Modbus ASCII LRC: two's complement of the 8-bit sum."""
    return (-sum(data)) & 0xFF


def _table() -> tuple[list[int], list[int]]:
    """The reflected CRC-16 (0xA001) byte table and, for each high byte, the table index that has it
    (the high bytes are a permutation: one step over a zero byte can be undone)."""
    table = []
    for v in range(256):
        s = v
        for _ in range(8):
            s = (s >> 1) ^ (0xA001 if s & 1 else 0)
        table.append(s)
    inv = [0] * 256
    for i, t in enumerate(table):
        inv[t >> 8] = i
    return table, inv


_T, _INV_HIGH = _table()
_T_INDEX = {t: v for v, t in enumerate(_T)}


def damaged_byte(frame: bytes) -> tuple[int, int] | None:
    """(position, value) of the one byte whose change would make a CRC-bad frame's CRC hold, or None.

    Only the positions a line fault damages are tried: the first byte (the address: a transmitter
    turned on late, its start bit cut) and the two CRC bytes (turned off early: the last byte cut).
    The CRC is linear, so the difference between the CRC found and the one computed (the syndrome)
    tells whether one byte at a position explains it: for the CRC bytes the syndrome lies in that
    byte alone; for the first byte it is that byte's error walked through the bytes after it, which is
    walked back here one step a byte (CRC-16/MODBUS's table makes each step invertible).  A random
    error elsewhere passes by chance with probability 255/65536 for the first byte and 1/256 for
    either CRC byte (more for the last data byte, whose error stays in the CRC's low byte about one
    time in eight); where two positions explain it neither is named.  So a fix found here on one
    frame is a hint, and on most damaged frames of one sender a finding.
    """
    n = len(frame)
    if n < 4:
        return None
    data = frame[:-2]
    computed = crc16_raw(data)
    found = frame[-2] | (frame[-1] << 8)
    s = computed ^ found
    if not s:
        return None
    fits = []
    if not s & 0xFF00:
        fits.append((n - 2, computed & 0xFF))
    if not s & 0x00FF:
        fits.append((n - 1, computed >> 8))
    for _ in range(n - 3):  # back over the data bytes after the first: its error's own table entry is left
        idx = _INV_HIGH[s >> 8]
        s = ((s ^ _T[idx]) << 8 | idx) & 0xFFFF
    v = _T_INDEX.get(s)
    if v:
        fits.append((0, frame[0] ^ v))
    return fits[0] if len(fits) == 1 else None  # two explanations: neither is known
