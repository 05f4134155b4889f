"""Modbus RTU frame lengths implied by function code and role.

`candidates(buf, p, end)` lists the lengths a frame starting at buf[p] can
have, each with the roles (CAN_REQ / CAN_RSP) that length fits.  A length
that depends on a byte not yet in the buffer comes back as NEED_AT(pos).
This is what lets the framer cut glued frames and rejoin split ones without
waiting for 3.5 characters of silence.
"""

from __future__ import annotations

from .frame import CAN_REQ, CAN_RSP

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
BROADCAST_FUNCTIONS = frozenset({0x05, 0x06, 0x0F, 0x10, 0x15, 0x16, 0x08})


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

    `end` is how far the buffer holds bytes (exclusive).  Unit 248-255 and
    function 0 give no candidates.
    """
    if p + 1 >= end:
        return [(Need(p + 1), 0)]
    unit = buf[p]
    fc = buf[p + 1]
    if unit > 247:
        return []
    if fc & 0x80:
        if unit == 0 or fc == 0x80:
            return []
        return [(5, CAN_RSP)]
    rule = RULES.get(fc)
    if rule is None:
        return []
    req = _length(rule[0], buf, p, end, True)
    rsp = None if unit == 0 else _length(rule[1], buf, p, end, False)
    if unit == 0 and fc not in BROADCAST_FUNCTIONS:
        req = None
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
