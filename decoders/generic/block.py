"""A block of registers (or bits) no model names, kept as its values until someone reads it.

A 125-register read response makes 125 point dicts, each built once and read by
nobody when the capture only goes to JSONL or MCAP.  `RegisterBlock` keeps the
table, first address, values and the ADU offset of the first value instead;
`Frame.points` turns it into the list of dicts the first time it is read, and
the JSON record is joined from a cached template of the block's constant parts
(names, addresses, spans) with the values' digits (sniffer.records).  Polls read
the same blocks over and over, so the templates, names and spans are cached per
(table, address, count, offset).

The points are the ones GenericModbus.point gives, in its key order:
{"name": "holding[8448]", "address": 8448, "raw": v, "value": v, "unit": None, "span": [a, b]}
(test_register_block checks both forms against the dicts on random blocks).
"""

from __future__ import annotations

import msgspec

BIT_SPACES = frozenset({"coil", "discrete"})
_CACHE_LIMIT = 4096  # entries per cache; polls repeat a few dozen blocks
_TEMPLATE_PIECES = 200_000  # template pieces kept in all (about 15 MB): a capture with many blocks clears it

_encode = msgspec.json.Encoder().encode
_span_cache: dict[tuple[int, int, bool], list[list[int]]] = {}
_name_cache: dict[tuple[str, int, int], list[str]] = {}
_template_cache: dict[tuple[str, int, int, int], list[bytes | None]] = {}
_template_pieces = 0


def spans(offset: int, n: int, bits: bool) -> list[list[int]]:
    """Spans of n registers (2 bytes each) or bits (their byte) from ADU offset `offset`.

    The span lists are shared between frames, as the names are: nothing may change one in place
    (the registry gives ASCII frames new ones).
    """
    key = (offset, n, bits)
    out = _span_cache.get(key)
    if out is None:
        if len(_span_cache) > _CACHE_LIMIT:
            _span_cache.clear()
        if bits:
            out = [[offset + (i >> 3), offset + (i >> 3) + 1] for i in range(n)]
        else:
            out = [[offset + 2 * i, offset + 2 * i + 2] for i in range(n)]
        _span_cache[key] = out
    return out


def names(space: str, addr: int, n: int) -> list[str]:
    """Names of a register block ("holding[8448]", ...)."""
    key = (space, addr, n)
    out = _name_cache.get(key)
    if out is None:
        if len(_name_cache) > _CACHE_LIMIT:
            _name_cache.clear()
        out = _name_cache[key] = [f"{space}[{a}]" for a in range(addr, addr + n)]
    return out


def _template(space: str, addr: int, n: int, offset: int) -> list[bytes | None]:
    """The block's JSON in 5 pieces a point: prefix, raw digits (None), ',"value":', value digits
    (None), suffix; the values' digits are put in the None places."""
    global _template_pieces
    key = (space, addr, n, offset)
    tpl = _template_cache.get(key)
    if tpl is None:
        if _template_pieces > _TEMPLATE_PIECES or len(_template_cache) > _CACHE_LIMIT:
            _template_cache.clear()
            _template_pieces = 0
        tpl = []
        sep = "["
        for name, a, (s0, s1) in zip(names(space, addr, n), range(addr, addr + n),
                                     spans(offset, n, space in BIT_SPACES)):
            tpl += [f'{sep}{{"name":"{name}","address":{a},"raw":'.encode(), None, b',"value":', None,
                    f',"unit":null,"span":[{s0},{s1}]}}'.encode()]
            sep = ","
        tpl[-1] += b"]"
        _template_cache[key] = tpl
        _template_pieces += len(tpl)
    return tpl


class RegisterBlock:
    """Consecutive values of one table from `addr` on; value i's bytes start at ADU offset `offset`
    (register i at offset + 2i, bit i in the byte offset + i // 8)."""

    __slots__ = ("space", "addr", "values", "offset")

    def __init__(self, space: str, addr: int, values: list[int], offset: int) -> None:
        self.space = space
        self.addr = addr
        self.values = values
        self.offset = offset

    def __len__(self) -> int:
        return len(self.values)

    def points(self) -> list[dict]:
        n = len(self.values)
        return [
            {"name": nm, "address": a, "raw": v, "value": v, "unit": None, "span": sp}
            for nm, a, v, sp in zip(names(self.space, self.addr, n), range(self.addr, self.addr + n), self.values,
                                    spans(self.offset, n, self.space in BIT_SPACES))
        ]

    def json(self) -> bytes:
        values = self.values
        if not values:
            return b"[]"
        digits = _encode(values)[1:-1].split(b",")
        out = _template(self.space, self.addr, len(values), self.offset).copy()
        out[1::5] = digits
        out[3::5] = digits
        return b"".join(out)

    def summary(self, limit: int = 6) -> str:
        """What _points_summary says of these points: "holding[8448]=1 holding[8449]=2 ... (+n)"."""
        values = self.values
        text = " ".join([f"{nm}={v}" for nm, v in zip(names(self.space, self.addr, min(len(values), limit)),
                                                      values)])
        if len(values) > limit:
            text += f" ... (+{len(values) - limit})"
        return text
