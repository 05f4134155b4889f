"""What a filter reads of one frame: its flags, the registers it touches, the text free words search.

`Facts` wraps one frame and works each of these out once, when a term first
asks; the store hands in what it already has (flags, registers).  A `Context`
says when the capture started (for `t:`) and what the drive models' parameter
ids are (`reg:12-00`); the TUI's FrameStore is one as well.
"""

from __future__ import annotations

from sniffer.frame import REQUEST, RESPONSE, Frame
from sniffer.analysis.flags import frame_flags
from sniffer.protocols import TABLES, modbus_range_ok, of_frame

_FIELD = "\x00"  # between the fields of one frame's search text

# the store's register column: table code << REG_SHIFT | first address, and a count column beside it
REG_SHIFT = 17
REG_MASK = (1 << REG_SHIFT) - 1
REG_NONE = -1  # the frame touches no register
REG_FRAME = -2  # more than one range (or too wide): ask the frame
TABLE_CODE = {t: i for i, t in enumerate(TABLES)}


def search_text(f: Frame) -> str:
    """What free text searches in a frame, lower case: summary, annotation codes and details, the raw
    bytes in hex, model, noise reason, and every decoded point's name, parameter id, unit and text
    (a summary names only the first few points).  Register numbers are matched as registers, not here."""
    parts = [f.summary]
    for a in f.annotations:
        parts.append(a.code)
        parts.append(a.detail)
    parts.append(f.raw.hex())
    parts.append(f.model or "")
    parts.append(f.noise_reason or "")
    if f.model != "generic":  # the generic decoder's points are named holding[300] ...: registers, not words
        seen = set()
        for p in f.points:
            seen.add(p["name"])
            seen.add(p.get("id") or "")
            seen.add(p.get("unit") or "")
            seen.add(p.get("text") or "")
        seen.discard("")
        parts.extend(seen)
    return _FIELD.join(parts).lower()


def matches_text(f: Frame, needle: str) -> bool:
    """The free-text test on one frame (needle lower case); a role name also matches that role."""
    return needle == f.role or needle in search_text(f)


def registers_of(f: Frame) -> list[tuple[str, int, int]]:
    """The registers (or bits) a frame touches, as (table, first, end) ranges (end exclusive).

    What the decoder recorded: the register-shadow writes (a read response's values, a confirmed
    write), else the addressed points (a write request; a damaged response's values); and what a
    request's address fields name where it carries no values (a read request, a write's echo).
    """
    out = [(t, start, start + len(raws)) for t, start, raws in f.writes]
    if not out:
        pts = f.points
        if pts:
            table = _table(f)
            if table is not None:
                for p in pts:
                    a = p.get("address")
                    if a is not None:
                        words = p.get("words")
                        out.append((table, a, a + (len(words) if words else 1)))
    if (not out or f.function == 0x17) and f.crc_ok is not False:
        named = _addressed(f)
        if named is not None:
            out.append(named)
    return out


def _table(f: Frame) -> str | None:
    p = of_frame(f.protocol)
    return None if p is None else p.table_of(f.function)


def _addressed(f: Frame) -> tuple[str, int, int] | None:
    """(table, first, end) of a request's (or a write echo's) address fields: Modbus 01H-04H and 17H
    requests name address and quantity, 05H / 06H an address, a 0FH / 10H response echoes address
    and quantity (application protocol 6.1-6.17); a PD-series 01H / 04H request names its parameter
    or CFG in its first DATA byte."""
    p = of_frame(f.protocol)
    fc = f.function
    if p is None or fc is None or fc & 0x80:
        return None
    table = p.table_of(fc)
    adu = f.adu
    if table is None:
        return None
    if p.family == "modbus":
        if len(adu) < 6:
            return None
        a = adu[2] << 8 | adu[3]
        if fc in (0x05, 0x06):
            return table, a, a + 1
        q = adu[4] << 8 | adu[5]
        if ((fc <= 0x04 or fc == 0x17) and f.role == REQUEST) or (fc in (0x0F, 0x10) and f.role == RESPONSE):
            return (table, a, a + q) if modbus_range_ok(fc, a, q) else None  # junk fields name no registers
        return None
    if fc in (0x01, 0x04) and f.role == REQUEST and len(adu) >= 4:
        return table, adu[3], adu[3] + 1
    return None


def register_cell(ranges: list[tuple[str, int, int]]) -> tuple[int, int]:
    """(reg, count) of the store's register columns for a frame's ranges: one table's contiguous
    registers exactly, REG_NONE for none, REG_FRAME where the frame itself must be asked."""
    if not ranges:
        return REG_NONE, 0
    table, lo, hi = ranges[0]
    for t, a, b in ranges[1:]:
        if t != table or a > hi or b < lo:
            return REG_FRAME, 0
        lo, hi = min(lo, a), max(hi, b)
    if hi - lo > 0xFFFF or lo > REG_MASK or lo < 0:
        return REG_FRAME, 0
    return TABLE_CODE[table] << REG_SHIFT | lo, hi - lo


def register_ids(registry) -> dict[str, tuple[tuple[str, str | None, int, int], ...]]:
    """Parameter id (lower case) -> ((model, table or None for either, first, end), ...) from the
    register maps of a decoder registry's models (TECO A510 "12-00", TDS-V8 "Cn-02")."""
    out: dict[str, set] = {}
    for d in (getattr(registry, "decoders", None) or {}).values():
        m = getattr(d, "map", None)
        if m is None:
            continue
        model = getattr(d, "model", None) or m.model_id
        for r in (*m.registers.values(), *m.inputs.values()):
            if r.id:
                out.setdefault(r.id.lower(), set()).add((model, r.table or None, r.addr, r.addr + r.words))
    return {k: tuple(sorted(v, key=lambda x: (x[0], x[1] or "", x[2]))) for k, v in out.items()}


class Context:
    """Where a filter runs: the capture's start (t0_ns, for `t:`) and the models' parameter ids."""

    def __init__(self, t0_ns: int = 0, ids: dict | None = None) -> None:
        self.t0_ns = t0_ns
        self.ids = ids or {}

    def resolve_id(self, word: str) -> tuple[tuple[str, str | None, int, int], ...]:
        return self.ids.get(word, ())


class Facts:
    """One frame as the terms read it; flags, registers and search text are worked out once, on demand."""

    __slots__ = ("frame", "ctx", "_flags", "_regs", "_text", "rates")

    def __init__(self, frame: Frame, ctx, flags: int | None = None, regs: list | None = None) -> None:
        self.frame = frame
        self.ctx = ctx
        self.rates: dict | None = None  # Rate -> passes, for this frame (filterlang.rate)
        self._flags = flags
        self._regs = regs
        self._text: str | None = None

    @property
    def flags(self) -> int:
        if self._flags is None:
            self._flags = frame_flags(self.frame)
        return self._flags

    @property
    def regs(self) -> list[tuple[str, int, int]]:
        if self._regs is None:
            self._regs = registers_of(self.frame)
        return self._regs

    @property
    def text(self) -> str:
        if self._text is None:
            self._text = search_text(self.frame)
        return self._text

    @property
    def table(self) -> str | None:
        """The table the frame's addressed points belong to."""
        return _table(self.frame)


__all__ = ["Context", "Facts", "REG_FRAME", "REG_MASK", "REG_NONE", "REG_SHIFT", "TABLE_CODE",
           "matches_text", "register_cell", "register_ids", "registers_of", "search_text"]
