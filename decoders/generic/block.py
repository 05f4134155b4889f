"""A block of registers (or bits) no model names, kept as its values until someone reads it.

A 125-register read response makes 125 point dicts, each built once and read by
nobody when the capture only goes to JSONL or MCAP.  `RegisterBlock` keeps the
table, first address, values and the ADU offset of the first value instead;
`Frame.points` turns it into the list of dicts the first time it is read, and
the JSON record is joined from a cached template of the block's constant parts
(names, addresses, spans) with the values' digits (sniffer.formats.records).  Polls read
the same blocks over and over, so the templates, names and spans are cached per
(table, address, count, offset).

The points are the ones GenericModbus.point gives, in its key order:
{"name": "holding[8448]", "address": 8448, "raw": v, "value": v, "unit": None, "span": [a, b]}
(test_register_block checks both forms against the dicts on random blocks).
"""

from __future__ import annotations

import msgspec

BIT_SPACES = frozenset({"coil", "discrete"})
_CACHE_LIMIT = 512  # entries per cache: polls repeat a few dozen blocks (damaged frames make one-off ones)
_TEMPLATE_PIECES = 50_000  # template pieces kept in all (about 3 MB): a capture with many blocks clears it

_encode = msgspec.json.Encoder().encode
_span_cache: dict[tuple[int, int, bool], list[list[int]]] = {}
_name_cache: dict[tuple[str, int, int], list[str]] = {}
_shapes: dict[tuple[str, int, int, int], _Shape] = {}
_shape_pieces = 0  # JSON template pieces held by _shapes


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


class _Shape:
    """What every block of one (table, address, count, offset) shares: the constant parts of its JSON
    and summary, and the last values written with their JSON and summary (a poll often reads what it
    read before, from this unit or another: equal values give the same text)."""

    __slots__ = ("space", "addr", "offset", "pieces", "summary_tpl", "last", "last_json", "last_summary")

    def __init__(self, space: str, addr: int, n: int, offset: int) -> None:
        self.space, self.addr, self.offset = space, addr, offset
        # the JSON in 5 pieces a point: prefix, raw digits (None), ',"value":', value digits (None), suffix
        pieces: list[bytes | None] = []
        sep = "["
        for name, a, (s0, s1) in zip(names(space, addr, n), range(addr, addr + n),
                                     spans(offset, n, space in BIT_SPACES)):
            pieces += [f'{sep}{{"name":"{name}","address":{a},"raw":'.encode(), None, b',"value":', None,
                       f',"unit":null,"span":[{s0},{s1}]}}'.encode()]
            sep = ","
        if pieces:
            pieces[-1] += b"]"
        self.pieces = pieces
        self.summary_tpl = _summary_template(space, addr, n, SUMMARY_LIMIT)
        self.last: list[int] | None = None
        self.last_json = self.last_summary = None


SUMMARY_LIMIT = 6  # points a summary names (GenericModbus's points_summary)


def _summary_template(space: str, addr: int, n: int, limit: int) -> str:
    tpl = " ".join([f"{nm}=%d" for nm in names(space, addr, min(n, limit))])
    return tpl + f" ... (+{n - limit})" if n > limit else tpl


def _shape(space: str, addr: int, n: int, offset: int) -> _Shape:
    global _shape_pieces
    key = (space, addr, n, offset)
    shape = _shapes.get(key)
    if shape is None:
        if _shape_pieces > _TEMPLATE_PIECES or len(_shapes) > _CACHE_LIMIT:
            _shapes.clear()
            _shape_pieces = 0
        shape = _shapes[key] = _Shape(space, addr, n, offset)
        _shape_pieces += len(shape.pieces)
    return shape


class RegisterBlock:
    """Consecutive values of one table from `addr` on; value i's bytes start at ADU offset `offset`
    (register i at offset + 2i, bit i in the byte offset + i // 8).  Table, address and offset are
    the shape's: a block holds its values and its shape only."""

    __slots__ = ("values", "shape")

    def __init__(self, space: str, addr: int, values: list[int], offset: int) -> None:
        self.values = values  # kept, not copied: nothing changes a decoded frame's values
        self.shape = _shape(space, addr, len(values), offset)

    def __len__(self) -> int:
        return len(self.values)

    def __reduce__(self):
        """Pickled as what makes it (a frame crossing to another process: sniffer.parallel)."""
        sh = self.shape
        return RegisterBlock, (sh.space, sh.addr, self.values, sh.offset)

    def points(self) -> list[dict]:
        sh, n = self.shape, len(self.values)
        return [
            {"name": nm, "address": a, "raw": v, "value": v, "unit": None, "span": sp}
            for nm, a, v, sp in zip(names(sh.space, sh.addr, n), range(sh.addr, sh.addr + n), self.values,
                                    spans(sh.offset, n, sh.space in BIT_SPACES))
        ]

    def samples(self):
        """(name, address, value) of each register (frame.PointBlock.samples)."""
        sh, n = self.shape, len(self.values)
        return zip(names(sh.space, sh.addr, n), range(sh.addr, sh.addr + n), self.values)

    def json(self) -> bytes:
        values, shape = self.values, self.shape
        if values == shape.last and shape.last_json is not None:
            return shape.last_json
        if not values:
            return b"[]"
        digits = _encode(values)[1:-1].split(b",")
        out = shape.pieces.copy()
        out[1::5] = digits
        out[3::5] = digits
        data = b"".join(out)
        if values != shape.last:
            shape.last, shape.last_summary = values, None
        shape.last_json = data
        return data

    def summary(self, limit: int = SUMMARY_LIMIT) -> str:
        """What points_summary says of these points: "holding[8448]=1 holding[8449]=2 ... (+n)"."""
        values, shape = self.values, self.shape
        if limit != SUMMARY_LIMIT:
            return _summary_template(shape.space, shape.addr, len(values), limit) % tuple(values[:limit])
        if values == shape.last and shape.last_summary is not None:
            return shape.last_summary
        text = shape.summary_tpl % tuple(values[:limit])
        if values != shape.last:
            shape.last, shape.last_json = values, None
        shape.last_summary = text
        return text
