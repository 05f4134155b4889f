"""The ACME Link framer: the start byte says the direction, the length byte the frame's size, a CRC ends it."""

from sniffer.frame import CAN_REQ, CAN_RSP
from sniffer.framing import PacketFramer

REQUEST_START, RESPONSE_START = 0x7E, 0x7F


def crc16_ccitt(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: polynomial 1021H, initial FFFFH, not reflected (ACME manual 9.3)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def frame(start: int, unit: int, cmd: int, data: bytes) -> bytes:
    """A whole frame (what a simulated line sends)."""
    body = bytes((unit, cmd, len(data))) + data
    return bytes((start,)) + body + crc16_ccitt(body).to_bytes(2, "big")


class AcmeFramer(PacketFramer):
    protocol = "acme-link"
    head_size = 4  # start, unit, cmd, len

    def frame_length(self, head: bytes):
        if head[0] not in (REQUEST_START, RESPONSE_START):
            return None  # not a frame start: noise up to the next silence
        return 4 + head[3] + 2

    def check(self, raw: bytes):
        want = crc16_ccitt(raw[1:-2])
        return int.from_bytes(raw[-2:], "big") == want, want

    def describe(self, frame) -> None:
        raw = frame.raw
        frame.unit, frame.function = raw[1], raw[2]
        frame.role_fits = CAN_REQ if raw[0] == REQUEST_START else CAN_RSP
        frame.adu = raw[1:-2]  # unit, cmd, len, data: what the decoder reads
