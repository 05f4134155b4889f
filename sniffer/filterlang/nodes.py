"""The parsed filter: a tree of terms, each tested on one frame (`test`) or on a store's columns (`rows`).

`test(facts)` is the meaning: True if the frame passes.  `rows(cols, cand)` is the
same test over the rows `cand` of a store, answered from its per-row columns
where they suffice: it returns (sure, maybe), the rows that pass for certain and
the rows only their frame can decide (a value of a decoded point, a frame that
touches registers in two places).  Terms on columns (unit, function, role,
flags, time, latency, registers, model) leave nothing to the frames; free
text is answered from the store's search text; a point's value narrows the rows
to those whose search text holds the point's name, and only those frames are
rebuilt.  `And` evaluates its cheapest terms first, each on the rows left.

`cols` is duck-typed (the TUI's FrameStore): t0_ns; `array` columns t_ns, unit,
function (-1: none), role (codes in role_code), flags, lat_us (-1: none), reg / nreg
(facts.register_cell), model (index into model_names); problems (the rows with a
problem flag, ascending); text_rows(rows, needle); resolve_id(id).

Leaves print as they were typed; `str(node)` is the filter's canonical text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sniffer.analysis.flags import F_PROBLEM
from sniffer.filterlang.facts import REG_FRAME, REG_MASK, REG_NONE, REG_SHIFT, TABLE_CODE
from sniffer.filterlang.values import Interval, RegRange

Rows = set  # a set of row numbers
_FAR_NEG, _FAR_POS = -(1 << 63), 1 << 63  # an open end of an interval on an integer column


class Node:
    cost = 0  # And runs the cheapest first

    def test(self, fx) -> bool:  # pragma: no cover - every node has one
        raise NotImplementedError

    def rows(self, cols, cand) -> tuple[Rows, Rows]:  # pragma: no cover
        raise NotImplementedError


# ---------------------------------------------------------------- leaves
@dataclass(frozen=True)
class Flag(Node):
    """err, crc, exc, timeout, fault, noise, warn: a problem bit of the frame (frameflags)."""

    src: str
    mask: int

    def test(self, fx) -> bool:
        return bool(fx.flags & self.mask)

    def rows(self, cols, cand):
        if self.mask == F_PROBLEM and isinstance(cand, range) and cand.step == 1:
            return {r for r in cols.problems if cand.start <= r < cand.stop}, set()
        col, mask = cols.flags, self.mask
        return {r for r in cand if col[r] & mask}, set()

    def __str__(self) -> str:
        return self.src


@dataclass(frozen=True)
class Field(Node):
    """u, fc, t or lat against intervals (u:1,2  fc:3..4  t:10s..20s  lat>20ms): a frame without the
    field (noise has no unit, a request no latency) never passes.  t is nanoseconds since the capture
    started, lat microseconds."""

    src: str
    key: str  # "u", "fc", "t", "lat"
    spans: tuple[Interval, ...]

    @property
    def cost(self) -> int:
        return 1 if self.key in ("u", "fc") else 2

    @property
    def points(self) -> frozenset | None:
        """The values, when every interval is one value (u:1,2): a set test on the column."""
        pts = [iv.point for iv in self.spans]
        return None if any(p is None for p in pts) else frozenset(pts)

    def _inside(self, v) -> bool:
        return any(v in iv for iv in self.spans)

    def value(self, fx):
        f = fx.frame
        k = self.key
        if k == "u":
            return f.unit
        if k == "fc":
            return None if f.function is None else f.function & 0x7F
        if k == "t":
            return f.t_ns - fx.ctx.t0_ns
        return None if f.latency_ms is None else round(f.latency_ms * 1000)

    def test(self, fx) -> bool:
        v = self.value(fx)
        return v is not None and self._inside(v)

    def _bounds(self, shift: int, least: int | None) -> list[tuple[int, int]]:
        """The intervals as inclusive integer bounds (every column holds integers), moved by `shift`
        (t: the capture's start) and from `least` on (-1 means none in the unit and latency columns)."""
        out = []
        for iv in self.spans:
            lo = _FAR_NEG if iv.lo is None else (math.floor(iv.lo) + 1 if iv.lo_excl else math.ceil(iv.lo))
            hi = _FAR_POS if iv.hi is None else (math.ceil(iv.hi) - 1 if iv.hi_excl else math.floor(iv.hi))
            out.append((lo + shift if least is None else max(lo, least), hi + shift))
        return out

    def rows(self, cols, cand):
        k, pts = self.key, self.points
        if k == "fc":
            col, inside = cols.function, self._inside
            if pts is not None:
                return {r for r in cand if col[r] >= 0 and col[r] & 0x7F in pts}, set()
            return {r for r in cand if col[r] >= 0 and inside(col[r] & 0x7F)}, set()
        if k == "u" and pts is not None and all(p >= 0 for p in pts):
            col = cols.unit
            return {r for r in cand if col[r] in pts}, set()
        col = {"u": cols.unit, "t": cols.t_ns, "lat": cols.lat_us}[k]
        out: Rows = set()
        for lo, hi in self._bounds(cols.t0_ns if k == "t" else 0, None if k == "t" else 0):
            out.update(r for r in cand if lo <= col[r] <= hi)
        return out, set()

    def __str__(self) -> str:
        return self.src


@dataclass(frozen=True)
class Choice(Node):
    """One of some names, kept as a small code per row (role:req,rsp  model:a510)."""

    src: str
    names: frozenset  # lower case

    cost = 1

    def value(self, frame) -> str:  # pragma: no cover - each kind has one
        raise NotImplementedError

    def column(self, cols) -> tuple:  # pragma: no cover - each kind has one
        """(the column, {code: name})."""
        raise NotImplementedError

    def test(self, fx) -> bool:
        return self.value(fx.frame) in self.names

    def rows(self, cols, cand):
        col, names = self.column(cols)
        codes = {c for c, n in names.items() if (n or "").lower() in self.names}
        return {r for r in cand if col[r] in codes}, set()

    def __str__(self) -> str:
        return self.src


@dataclass(frozen=True)
class Roles(Choice):
    def value(self, frame) -> str:
        return frame.role

    def column(self, cols) -> tuple:
        return cols.role, {c: n for n, c in cols.role_code.items()}


@dataclass(frozen=True)
class Models(Choice):
    def value(self, frame) -> str:
        return (frame.model or "").lower()

    def column(self, cols) -> tuple:
        return cols.model, dict(enumerate(cols.model_names))


@dataclass(frozen=True)
class Links(Choice):
    """link:drives,pumps  the frames of these links (a capture of several links; one line has none)."""

    def value(self, frame) -> str:
        return (frame.link or "").lower()

    def column(self, cols) -> tuple:
        return cols.link, dict(enumerate(cols.link_names))


@dataclass(frozen=True)
class Regs(Node):
    """reg:2520H  reg:holding[300]..holding[310]  reg:12-00: frames touching any of these registers.  A
    parameter id is looked up in the models' register maps (that model's frames at that address) and
    also matches a decoded point carrying that id."""

    src: str
    ranges: tuple[RegRange, ...]
    ids: tuple[str, ...] = ()  # lower case
    point_ids: bool = True  # an id also matches a point carrying it (a free word finds those as text)

    cost = 3

    def _resolved(self, ctx) -> list[tuple[str, RegRange]]:
        return [(model, RegRange(table, lo, hi - 1)) for i in self.ids for model, table, lo, hi in ctx.resolve_id(i)]

    def test(self, fx) -> bool:
        ranges = self.ranges
        regs = fx.regs
        for t, lo, hi in regs:
            for s in ranges:
                if s.overlaps(t, lo, hi):
                    return True
        if not self.ids:
            return False
        model = fx.frame.model
        for m, s in self._resolved(fx.ctx):
            if m == model and any(s.overlaps(t, lo, hi) for t, lo, hi in regs):
                return True
        return self.point_ids and any((p.get("id") or "").lower() in self.ids for p in fx.frame.points)

    def rows(self, cols, cand):
        reg, nreg, model = cols.reg, cols.nreg, cols.model
        plain = [(None if s.table is None else TABLE_CODE[s.table], s.lo, s.hi) for s in self.ranges]
        codes = {m: i for i, m in enumerate(cols.model_names)}
        by_model = [(codes[m], None if s.table is None else TABLE_CODE[s.table], s.lo, s.hi)
                    for m, s in self._resolved(cols) if m in codes]
        sure: Rows = set()
        maybe: Rows = set()
        for r in cand:
            v = reg[r]
            if v == REG_NONE:
                continue
            if v == REG_FRAME:
                maybe.add(r)
                continue
            t, lo = v >> REG_SHIFT, v & REG_MASK
            hi = lo + nreg[r]
            for st, slo, shi in plain:
                if slo < hi and lo <= shi and (st is None or st == t):
                    sure.add(r)
                    break
            else:
                if by_model:
                    m = model[r]
                    for mc, st, slo, shi in by_model:
                        if mc == m and slo < hi and lo <= shi and (st is None or st == t):
                            sure.add(r)
                            break
        if self.ids and self.point_ids:  # a point carrying the id: only frames whose search text holds it
            rest = [r for r in cand if r not in sure] if sure else cand
            for i in self.ids:
                maybe.update(cols.text_rows(rest, i))
        maybe -= sure
        return sure, maybe

    def __str__(self) -> str:
        return self.src


@dataclass(frozen=True)
class Text(Node):
    """A free word or a quoted phrase: found in the frame's search text (facts.search_text), a role
    name matches that role, and a word that reads as a register (300, 012CH, holding[300], 12-00)
    also matches the frames touching that register."""

    src: str
    needle: str  # lower case
    regs: Regs | None = None

    cost = 5

    def test(self, fx) -> bool:
        if self.needle == fx.frame.role or self.needle in fx.text:
            return True
        return self.regs is not None and self.regs.test(fx)

    def rows(self, cols, cand):
        sure = set(cols.text_rows(cand, self.needle))
        if self.regs is None:
            return sure, set()
        s, m = self.regs.rows(cols, [r for r in cand if r not in sure])
        return sure | s, m

    def __str__(self) -> str:
        return self.src


@dataclass(frozen=True)
class Compare(Node):
    """A decoded point against a value: `"Output frequency" > 50`, `2524H >= 5000`, `"fault code" = OV`.

    The point is picked by name or parameter id (case-insensitive), or by register (a number, 012CH,
    holding[300]).  A number compares with the point's scaled value (a unit after it, 50Hz, must be the
    point's); text compares with the point's text (an enum's or its mnemonic: "OV — Over voltage" = OV)
    or its value, `~` when it contains it.  A frame passes when one of its points does; with != when it
    has the point and none of them equals the value.  A provisional point (scaled through a register not
    known yet: "Output frequency (% of Cn-02)", docs/values.md) is picked only by its own name, or with a
    number in its unit (`0025H > 50%`): never as the value it will be once scaled."""

    src: str
    name: str | None  # lower case, or None when picked by register
    table: str | None
    address: int | None
    op: str
    number: float | None
    unit: str  # lower case, "" for any
    text: str  # lower case (the value as typed, for text comparisons)
    spans: tuple[Interval, ...]  # where the number passes (values.comparison_intervals)

    cost = 8

    def _points(self, fx) -> list[dict]:
        f = fx.frame
        if self.name is None:
            table = fx.table
            if self.table is not None and table != self.table:
                return []
            return [p for p in f.points if p.get("address") == self.address and self._takes(p)]
        n, k = self.name, len(self.name)
        return [p for p in f.points if (len(p["name"]) == k and p["name"].lower() == n)
                or ((p.get("id") or "").lower() == n and self._takes(p))]

    def _takes(self, p: dict) -> bool:
        """A point picked by its register or parameter id: a provisional one only with a number in its unit."""
        return not p.get("provisional") or (self.number is not None and bool(self.unit)
                                            and (p.get("unit") or "").lower() == self.unit)

    def _equal_or_passes(self, p: dict) -> bool:
        if self.number is not None:
            v = p.get("value")
            if type(v) is bool:
                v = int(v)
            if not isinstance(v, (int, float)) or (self.unit and (p.get("unit") or "").lower() != self.unit):
                return False
            if self.op == "!=":
                return v == self.number
            return any(v in iv for iv in self.spans)
        text = (p.get("text") or "").lower()
        value = str(p.get("value")).lower()
        want = self.text
        if self.op == "~":
            return want in text or want in value
        return want in (text, value, text.split(" — ")[0])

    def test(self, fx) -> bool:
        pts = self._points(fx)
        if self.op == "!=":
            return bool(pts) and not any(self._equal_or_passes(p) for p in pts)
        return any(self._equal_or_passes(p) for p in pts)

    def rows(self, cols, cand):
        if self.name is None:
            s, m = Regs("", (RegRange(self.table, self.address, self.address),)).rows(cols, cand)
            return set(), s | m
        return set(), set(cols.text_rows(cand, self.name))

    def __str__(self) -> str:
        return self.src


# ---------------------------------------------------------------- logic
@dataclass(frozen=True)
class Group(Node):
    """Terms joined by And or Or: as costly as its dearest."""

    items: tuple[Node, ...]

    @property
    def cost(self) -> int:
        return max(i.cost for i in self.items)


@dataclass(frozen=True)
class And(Group):
    def test(self, fx) -> bool:
        return all(i.test(fx) for i in self.items)

    def rows(self, cols, cand):
        sure, maybe = None, set()
        for item in sorted(self.items, key=lambda i: i.cost):
            pool = cand if sure is None else (sure | maybe if maybe else sure)
            s, m = item.rows(cols, pool)
            if sure is None:
                sure, maybe = s, m
            else:
                sure = s - maybe if maybe else s
                maybe = (s | m) - sure
        return sure, maybe

    def __str__(self) -> str:
        return " ".join(f"({i})" if isinstance(i, Or) else str(i) for i in self.items)


@dataclass(frozen=True)
class Or(Group):
    def test(self, fx) -> bool:
        return any(i.test(fx) for i in self.items)

    def rows(self, cols, cand):
        sure, maybe = set(), set()
        for item in sorted(self.items, key=lambda i: i.cost):
            s, m = item.rows(cols, [r for r in cand if r not in sure] if sure else cand)
            sure |= s
            maybe |= m
        return sure, maybe - sure

    def __str__(self) -> str:
        return " or ".join(str(i) for i in self.items)


@dataclass(frozen=True)
class Not(Node):
    item: Node

    @property
    def cost(self) -> int:
        return self.item.cost

    def test(self, fx) -> bool:
        return not self.item.test(fx)

    def rows(self, cols, cand):
        s, m = self.item.rows(cols, cand)
        return {r for r in cand if r not in s and r not in m}, m

    def __str__(self) -> str:
        inner = self.item
        return f"!({inner})" if isinstance(inner, (And, Or)) else f"!{inner}"

