"""Modbus RTU frame lengths implied by function code and role.

`candidates(buf, p, end)` lists the lengths a frame starting at buf[p] can
have, each with the roles (CAN_REQ / CAN_RSP) that length fits.  A length
that depends on a byte not yet in the buffer comes back as NEED_AT(pos).
This is what lets the framer cut glued frames and rejoin split ones without
waiting for 3.5 characters of silence.
"""

from __future__ import annotations

from sniffer.frame import CAN_REQ, CAN_RSP

MAX_ADU = 256  # Modbus RTU ADU limit

# Length rules: int = fixed length; (offset, add) = buf[p+offset] + add;
# (offset, add, 2) = 16-bit big-endian count at p+offset + add; "mei" = 2B/0E walk.
_BC2 = (2, 5)  # unit fc bytecount data... crc
RULES: dict[int, tuple] = {
    0x01: (8, _BC2),
    0x02: (8, _BC2),
    0x03: (8, _BC2),
    0x04: (8, _BC2),
    0x05: (8, 8),
    0x06: (8, 8),
    0x07: (4, 5),
    0x08: (8, 8),
    0x0B: (4, 8),
    0x0C: (4, _BC2),
    0x0F: ((6, 9), 8),
    0x10: ((6, 9), 8),
    0x11: (4, _BC2),
    0x14: (_BC2, _BC2),
    0x15: (_BC2, _BC2),
    0x16: (10, 10),
    0x17: ((10, 13), _BC2),
    0x18: (6, (2, 6, 2)),
    0x2B: ("mei", "mei"),
}
KNOWN_FUNCTIONS = frozenset(RULES)
BROADCAST_FUNCTIONS = frozenset({0x05, 0x06, 0x0F, 0x10, 0x15, 0x16, 0x08})  # writes (and 08) a broadcast may carry


class Need(int):
    """A candidate whose length needs the byte at this absolute buffer index."""


def _length(rule, buf, p: int, end: int, request: bool):
    if type(rule) is int:
        return rule
    if rule == "mei":
        return _mei_length(buf, p, end, request)
    off = p + rule[0]
    if len(rule) == 3:
        if off + 1 >= end:
            return Need(off + 1)
        return ((buf[off] << 8) | buf[off + 1]) + rule[1]
    if off >= end:
        return Need(off)
    return buf[off] + rule[1]


def _mei_length(buf, p: int, end: int, request: bool):
    """2B/0E Read Device Identification; other MEI types have no known length."""
    if p + 2 >= end:
        return Need(p + 2)
    if buf[p + 2] != 0x0E:
        return None
    if request:
        return 7
    if p + 7 >= end:
        return Need(p + 7)
    n = buf[p + 7]
    q = p + 8
    for _ in range(n):
        if q + 1 >= end:
            return Need(q + 1)
        q += 2 + buf[q + 1]
        if q - p > MAX_ADU:
            return None
    return q - p + 2


def candidates(buf, p: int, end: int) -> list[tuple[int, int]]:
    """[(length or Need, can_bits)] for a frame at buf[p]; shortest first, equal lengths merged.

    `end` is how far the buffer holds bytes (exclusive).  Function 0, 80H and
    unknown codes give no candidates.  Every unit gets the same lengths: a
    reserved unit (248-255) or unit 0 is annotated, never a reason to drop a
    frame whose CRC holds (gateways and discovery use 248-255; a slave may
    answer a broadcast, a device may be set to address 0).
    """
    if p + 1 >= end:
        return [(Need(p + 1), 0)]
    fc = buf[p + 1]
    if fc & 0x80:
        if fc == 0x80:
            return []
        return [(5, CAN_RSP)]
    rule = RULES.get(fc)
    if rule is None:
        return []
    req = _length(rule[0], buf, p, end, True)
    rsp = _length(rule[1], buf, p, end, False)
    out: list[tuple[int, int]] = []
    if req is not None and rsp is not None and req == rsp and type(req) is int:
        return [(req, CAN_REQ | CAN_RSP)]
    if req is not None and (type(req) is Need or 4 <= req <= MAX_ADU):
        out.append((req, CAN_REQ))
    if rsp is not None and (type(rsp) is Need or 4 <= rsp <= MAX_ADU):
        out.append((rsp, CAN_RSP))
    if len(out) == 2 and type(out[0][0]) is int and type(out[1][0]) is int and out[1][0] < out[0][0]:
        out.reverse()
    return out


def roles(adu: bytes, can: int) -> tuple[int, str | None]:
    """Narrow the roles a frame's length allowed by what its bytes say; (can, why) where why
    names evidence that contradicts the length's roles (None when nothing does).

    * a function code with 80H set is an exception: never a request;
    * 01-04 with 8 bytes and byte count 3: as a response 03/04 would need an even
      count (a request), as a request 01/02 a quantity of 1..2000;
    * 14H (read file record): a request's byte count is 7 bytes per sub-request,
      each starting with reference type 06; a response is sub-responses (length,
      06, data) adding up to the byte count;
    * 15H (write file record), request and response alike: groups of 06, file,
      record, length and 2 x length data bytes adding up to the byte count.
    """
    if len(adu) < 3:
        return can, None
    fc = adu[1]
    if fc & 0x80:
        return CAN_RSP, None
    if can != CAN_REQ | CAN_RSP:
        return can, None
    if fc in (0x03, 0x04) and len(adu) == 6 and adu[2] & 1:
        return CAN_REQ, None
    if fc in (0x01, 0x02) and len(adu) == 6:
        q = (adu[4] << 8) | adu[5]
        if not 1 <= q <= 2000:
            return CAN_RSP, None
        return can, None
    if fc == 0x14:
        bc = adu[2]
        body = adu[3:]
        if len(body) != bc:
            return can, None
        req = bc % 7 == 0 and bc > 0 and all(body[k] == 6 for k in range(0, bc, 7))
        rsp = _walk_file_response(body)
        if req and not rsp:
            return CAN_REQ, None
        if rsp and not req:
            return CAN_RSP, None
        if not (req or rsp):
            return can, f"byte count {bc}: neither 7-byte sub-requests nor sub-responses (length, 06, data)"
        return can, None
    if fc == 0x15 and len(adu) - 3 == adu[2] and not _walk_file_write(adu[3:]):
        return can, f"byte count {adu[2]}: not groups of (06, file, record, length, data)"
    return can, None


def _walk_file_response(body: bytes) -> bool:
    q = 0
    while q < len(body):
        n = body[q]
        if n < 1 or q + 1 >= len(body) or body[q + 1] != 6:
            return False
        q += 1 + n
    return q == len(body) and q > 0


def _walk_file_write(body: bytes) -> bool:
    q = 0
    while q < len(body):
        if body[q] != 6 or q + 7 > len(body):
            return False
        q += 7 + 2 * ((body[q + 5] << 8) | body[q + 6])
    return q == len(body) and q > 0
