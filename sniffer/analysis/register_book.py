"""Register watch: each unit's register shadow, with names, scaled values and history.

The decoders record on every frame what decoding it wrote into its unit's
register shadow (`Frame.writes`: [[table, start, [raw, ...]], ...], see
decoders.base.UnitState.commit).  `RegisterBook` applies those writes as the
frame enters the store, so a local capture, a replay and a viewer attached
over a socket (frames rebuilt from their records) build the same watch, and
it is the decoders' shadow.  A written value takes its name, scaled value,
unit and text from a point at that (unit, table, address) whose raw value is
the one written: the frame's own (a read response, a single write's echo),
else the latest one of a frame that wrote nothing (the write request a
response confirmed); without one it shows the raw number, or keeps the value
shown if the raw number did not change.

A value of several registers (a u32, a float, a string: decoders/regtypes.py)
is one point with `words`, its registers as written: where a write holds those
words at the point's address, the value is one row at its first address (raw =
the registers joined) and the rows its other registers had are dropped (they
were shown raw while only part of the value had been read).  A point of one
register of such a value (`part`: a read or write of half a u32) never
overwrites the value's row nor enters its plot: while the row exists it is
marked stale ("word 2/2 now 0007H: value as of the last whole read") until a
whole read or write sets it again; without a row, the register shows raw.

A row's history is one series: the values of one model, name and engineering unit
(the point's, as the decoder gave it: docs/values.md).  A value decoded otherwise (a
unit identified after its first answers were decoded as generic registers, an
A510 found to run at 0.1 Hz per count, a TDS-V8 frequency that was provisional,
in % of Cn-02, until Cn-02 was read) starts the row's history again; with
`retired` > 0 the book keeps that many of the earlier series (`retired_rows`: the
report draws them under their own name and unit), else they are dropped.  No plot
draws one series' values in another's unit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from decoders.generic.block import RegisterBlock, names

from sniffer.frame import Frame, unit_key
from sniffer.protocols import of_frame
from sniffer.analysis.history import CAP, Series, cap_for, thin_queued

THIN_PER_FRAME = 2  # queued histories thinned per frame applied (about 0.6 ms each at 8,192 samples)


def table_of(f: Frame) -> str | None:
    """The shadow table a frame's addressed points belong to, or None."""
    p = of_frame(f.protocol)
    return None if p is None else p.table_of(f.function)


@dataclass
class RegisterValue:
    unit: int
    table: str
    address: int
    name: str
    value: object
    raw: object
    eng_unit: str | None
    text: str
    t_ns: int
    changed_ns: int
    changes: int = 0
    history: Series = field(default_factory=Series)  # every numeric value shown: (t, value, frame index)
    id: str = ""
    words: int = 1  # registers the value takes (address .. address + words - 1)
    model: str | None = None  # the model the value was decoded as (with name and eng_unit: its series)

    @property
    def address_text(self) -> str:
        """The address as the manuals write it: "2520H", or "2510H..2511H" for a value of several registers."""
        a = self.address
        return f"{a:04X}H" if self.words == 1 else f"{a:04X}H..{a + self.words - 1:04X}H"

    @property
    def title(self) -> str:
        """The name, led by the parameter id where the map has one (and the name does not hold it)."""
        return self.name if not self.id or self.id in self.name else f"{self.id} {self.name}"


_NUMBER = (int, float)  # not bool: a bit is plotted from its raw value


class RegisterBook:
    """The latest value of every register per unit, changes, history: the frames' `writes` applied."""

    def __init__(self, history_cap: int = CAP, retired: int = 0) -> None:
        self.history_cap = history_cap
        self.retired_cap = retired  # earlier series kept (see the module doc)
        self.retired: list[RegisterValue] = []  # samples kept per register at most (history.py thins beyond)
        self._cap = history_cap  # what each keeps now: less as registers share the budget (history.cap_for)
        self.values: dict[tuple[int, str, int], RegisterValue] = {}
        # the latest point per register of a frame that wrote nothing itself (a write request, whose
        # response confirms it without points of its own)
        self.points: dict[tuple[int, str, int], dict] = {}
        self.version = 0  # bumped on every update
        self.dropped = 0  # rows dropped so far (their registers joined into a value of several)
        self.thin_queue: list[Series] = []  # histories over their cap, thinned a few per frame (history.py)

    def frame(self, f: Frame) -> None:
        """Apply one frame (in arrival order): its writes, named by its own points or earlier ones."""
        self._frame(f)
        if self.thin_queue:
            thin_queued(self.thin_queue, THIN_PER_FRAME)

    def _frame(self, f: Frame) -> None:
        """Apply a frame's `writes` to the rows, each register named by the point that decodes its raw value.

        A read response of unnamed registers goes the short way (`_block`: no point dicts to match).
        A frame that wrote nothing (a write request) only remembers its points, so the response that
        confirms the write can name the registers.  For each written register the naming point is the
        frame's own at that address (same table) if it decodes this raw value (`_holds`), else the latest
        remembered one that does, else none (the row shows the raw number).  A point that is half of a
        multi-register value (`part`) marks that value's row stale instead of overwriting it; a point
        with `words` takes its registers as one row at its first address and drops the rows its other
        registers had.  The common case, a register polled again with the same raw value, is updated
        inline (value, time, history) rather than through `set`: this runs for every frame a viewer
        stores, so it is the hot path.  `version` is bumped once per frame that wrote.
        """
        unit = unit_key(f)  # a unit of its link, in a capture of several links
        if unit is None:
            return
        blk = f._points
        if type(blk) is RegisterBlock and f.writes and self._block(f, blk):
            return
        pts = f.points
        table = table_of(f) if pts and f.crc_ok is not False else None
        writes = f.writes
        if not writes:
            if table is not None:  # a request's points name what its response may confirm
                seen = self.points
                for p in pts:
                    a = p.get("address")
                    if a is not None:
                        seen[(unit, table, a)] = p
            return
        own = {p.get("address"): p for p in pts} if table is not None else {}
        seen, values, t_ns, model = self.points, self.values, f.t_ns, f.model
        for wtable, start, raws in writes:
            mine = own if wtable == table else {}
            n, i = len(raws), 0
            while i < n:
                raw = raws[i]
                a = start + i
                key = (unit, wtable, a)
                p = mine.get(a)
                if p is None or not _holds(p, raws, i):
                    p = seen.get(key)
                    if p is not None and not _holds(p, raws, i):
                        p = None
                step = 1
                part = p.get("part") if p is not None else None
                if part is not None and self._stale(unit, wtable, a, part, raw, t_ns):
                    i += 1
                    continue
                if p is not None:
                    words = p.get("words")
                    if words is not None:  # one value of these registers
                        raw, step = p["raw"], len(words)
                        if step > 1:
                            self._drop(unit, wtable, a + 1, a + step)
                    rv = values.get(key)
                    if rv is not None and rv.raw == raw:  # polled again, unchanged (most writes): set() inline
                        v, name, eng = p.get("value", raw), p.get("name") or rv.name, p.get("unit")
                        if name != rv.name or eng != rv.eng_unit or model != rv.model:
                            self._series(rv, model, name, eng)
                        rv.id = p.get("id") or ""
                        rv.value, rv.text, rv.t_ns = v, p.get("text") or "", t_ns
                        if type(v) in _NUMBER:
                            rv.history.add(t_ns, v, f.index)
                        i += step
                        continue
                self.set(key, raw, p, t_ns, step, f.index, model)
                i += step
        self.version += 1

    def _block(self, f: Frame, blk: RegisterBlock) -> bool:
        """`frame` for a read response of registers no model names (decoders.generic.block), without
        its point dicts: each point is named `holding[a]` and holds its raw value, so where the frame
        wrote the block's own values this is what `frame` does.  False (nothing done) otherwise."""
        sh = blk.shape
        writes = f.writes
        if len(writes) != 1:
            return False
        wtable, start, raws = writes[0]
        if start != sh.addr or raws != blk.values or wtable != table_of(f) or f.crc_ok is False:
            return False
        unit, t_ns, index, values, model = unit_key(f), f.t_ns, f.index, self.values, f.model
        for a, nm, raw in zip(range(start, start + len(raws)), names(sh.space, start, len(raws)), raws):
            key = (unit, wtable, a)
            rv = values.get(key)
            if rv is not None and rv.raw == raw:  # polled again, unchanged: as in `frame`
                if nm != rv.name or rv.eng_unit is not None or model != rv.model:
                    self._series(rv, model, nm, None)
                rv.id, rv.value, rv.text, rv.t_ns = "", raw, "", t_ns
                if type(raw) in _NUMBER:
                    rv.history.add(t_ns, raw, index)
            else:
                self.set(key, raw, {"name": nm, "raw": raw, "value": raw, "unit": None}, t_ns, 1, index, model)
        self.version += 1
        return True

    def _stale(self, unit: int, table: str, a: int, part: list, raw, t_ns: int) -> bool:
        """Register a is word part[0] + 1 of a value of part[1] registers: mark that value's row stale
        (True) rather than show the half as the value; False when there is no such row."""
        k, w = part
        rv = self.values.get((unit, table, a - k))
        if rv is None or rv.words != w:
            return False
        note = f"word {k + 1}/{w} now {raw:04X}H: value as of the last whole read"
        if rv.text != note:
            rv.text = note
            rv.changed_ns = t_ns
            rv.changes += 1
        rv.t_ns = t_ns
        if k:
            self._drop(unit, table, a, a + 1)  # its own raw row, if an earlier half made one
        return True

    def _drop(self, unit: int, table: str, lo: int, hi: int) -> None:
        """Registers lo..hi-1 now belong to the value at lo - 1: their own rows go."""
        values = self.values
        for a in range(lo, hi):
            if values.pop((unit, table, a), None) is not None:
                self.dropped += 1

    def set(self, key: tuple[int, str, int], raw, p: dict | None, t_ns: int, words: int = 1,
            index: int = -1, model: str | None = None) -> None:
        """Register `key` now holds `raw` (with `words` > 1: the value of that many registers from it);
        `p` is a point decoding that raw value, if there is one, as `model` decoded it; `index` the frame
        that brought it."""
        rv = self.values.get(key)
        if rv is None:
            unit, table, addr = key
            cap = cap_for(len(self.values) + 1, self.history_cap)
            if cap != self._cap:  # one more register sharing the history budget: each keeps less
                self._cap = cap
                for other in self.values.values():
                    other.history.cap = cap
            rv = self.values[key] = RegisterValue(unit, table, addr, f"{table}[{addr}]", raw, raw, None, "",
                                                  t_ns, t_ns, history=Series(cap, self.thin_queue))
        elif rv.raw != raw:
            rv.changed_ns = t_ns
            rv.changes += 1
        rv.words = words
        if p is not None:
            name, eng = p.get("name") or rv.name, p.get("unit")
            if name != rv.name or eng != rv.eng_unit or model != rv.model:
                self._series(rv, model, name, eng)
            rv.id = p.get("id") or ""
            rv.value, rv.text = p.get("value", raw), p.get("text") or ""
        elif rv.raw != raw:  # no decoded point for this new value: the number the shadow holds, as a register
            name = f"{rv.table}[{rv.address}]"
            if name != rv.name or rv.eng_unit is not None:
                self._series(rv, rv.model, name, None)
            rv.id, rv.value, rv.text = "", raw, ""
        if type(rv.value) in _NUMBER:
            rv.history.add(t_ns, rv.value, index)
        rv.raw, rv.t_ns = raw, t_ns

    def _series(self, rv: RegisterValue, model: str | None, name: str, eng_unit: str | None) -> None:
        """The row's values are now another series (model, name, unit): its history starts again; the
        earlier one is kept in `retired` (up to `retired_cap`) or dropped."""
        if rv.history.seen:
            if self.retired_cap:
                self.retired.append(dataclasses.replace(rv))  # shares the old history
                if len(self.retired) > self.retired_cap:
                    del self.retired[0]
            rv.history = Series(rv.history.cap, self.thin_queue)
        rv.model, rv.name, rv.eng_unit = model, name, eng_unit

    def rows(self, unit: int | None = None) -> list[RegisterValue]:
        """The rows in (unit, table, address) order."""
        keys = sorted(k for k in self.values if unit is None or k[0] == unit)
        return [self.values[k] for k in keys]


def _holds(p: dict, raws: list, i: int) -> bool:
    """Does point `p` decode the registers a write holds from its index i on?"""
    words = p.get("words")
    if words is None:
        return p.get("raw") == raws[i]
    return raws[i:i + len(words)] == words
