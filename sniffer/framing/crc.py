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
