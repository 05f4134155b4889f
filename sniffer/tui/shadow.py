"""Register watch: the decoders' register shadow per unit, with names, scaled values and history.

The decoders keep, per unit, the last raw value of every register and bit they
have seen or seen written (decoders.base.UnitState: holding, input, coils,
discrete), on the capture thread.  `ShadowTap` runs there, inside the TuiSink:
right after a frame is decoded it reads the shadow entries that frame can have
set (its points' addresses, or its request's for a write response) and, every
half second and at the end of the capture, sweeps the whole shadow for
anything else that changed.  What it read travels with the frame's sequence
number to the UI thread, where `RegisterBook` applies it as that frame enters
the store, so values, changes and history line up with the frame list and the
UI thread never touches the decoders' dicts.

Without a registry (a viewer fed frame records over a socket) the book builds
the same shadow from the decoded points: a read response's values, a write
once its response confirms it, a broadcast write at once.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

from ..frame import Frame
from ..protocols import of_frame

HISTORY = 120  # values kept per register for the plot
SWEEP_S = 0.5  # wall-clock seconds between whole-shadow sweeps on the capture thread
_PENDING_WRITES = 1024  # write requests remembered until their response
# UnitState attribute -> the watch's table name
SHADOW_TABLES = (("holding", "holding"), ("input", "input"), ("coils", "coil"), ("discrete", "discrete"))
_ATTR = {table: attr for attr, table in SHADOW_TABLES}


def table_of(f: Frame) -> str | None:
    """The shadow table a frame's addressed points belong to, or None."""
    p = of_frame(f.protocol)
    return None if p is None else p.table_of(f.function)


def _commit_points(f: Frame, pending: dict) -> tuple[str | None, list]:
    """(table, points) a frame puts into the shadow: a response its own points (or its write
    request's), a broadcast its own; a request is remembered until its response."""
    pts = f.points
    if f.role != "response" and f.unit != 0:
        if pts and f.role == "request":
            pending[f.index] = (table_of(f), pts)
            if len(pending) > _PENDING_WRITES:  # unanswered ones
                del pending[next(iter(pending))]
        return None, []
    req = pending.pop(f.pair, None) if f.pair is not None else None
    if not pts and req is not None:
        return req
    return table_of(f), pts


class ShadowTap:
    """Capture-thread side: what the registry's shadow says after each frame (see the module doc)."""

    def __init__(self, states: dict, clock=time.monotonic) -> None:
        self.states = states  # DecoderRegistry.states: unit -> UnitState, mutated by the decoders
        self.mirror: dict[tuple[int, str], dict[int, int]] = {}  # what has been reported, per (unit, table)
        self._pending: dict[int, tuple[str | None, list]] = {}
        self._clock = clock
        self._next_sweep = clock() + SWEEP_S
        self._frames = 0

    def observe(self, f: Frame) -> list | None:
        """[(table, address, raw, point or None)] the frame set in the shadow, read right after its decode."""
        if f.unit is None or f.protocol == "noise":
            return None
        table, pts = _commit_points(f, self._pending)
        if not pts or table is None:
            return None
        st = self.states.get(f.unit)
        if st is None:
            return None
        d = getattr(st, _ATTR[table])
        m = self.mirror.get((f.unit, table))
        if m is None:
            m = self.mirror[(f.unit, table)] = {}
        out = []
        for p in pts:
            a = p.get("address")
            v = d.get(a) if a is not None else None
            if v is None:
                continue
            if v == p.get("raw"):
                out.append((table, a, v, p))
                m[a] = v
            elif m.get(a) != v:  # the decoder kept something else: report the shadow's value
                out.append((table, a, v, None))
                m[a] = v
        return out or None

    def due(self) -> bool:
        self._frames += 1
        if self._frames & 63:
            return False
        now = self._clock()
        if now < self._next_sweep:
            return False
        self._next_sweep = now + SWEEP_S
        return True

    def sweep(self) -> list[tuple[int, list]]:
        """[(unit, [(table, address, raw, None)])] for every entry that differs from what was reported."""
        out = []
        for unit, st in list(self.states.items()):
            changed = []
            for attr, table in SHADOW_TABLES:
                d = getattr(st, attr)
                m = self.mirror.get((unit, table))
                if m is None:
                    if not d:
                        continue
                    m = self.mirror[(unit, table)] = {}
                if m == d:
                    continue
                for a, v in list(d.items()):
                    if m.get(a) != v:
                        changed.append((table, a, v, None))
                        m[a] = v
            if changed:
                out.append((unit, changed))
        return out


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
    history: deque = field(default_factory=lambda: deque(maxlen=HISTORY))
    id: str = ""


_NUMBER = (int, float)  # not bool: a bit is plotted from its raw value


class RegisterBook:
    """UI-thread side: the latest value of every register per unit, changes, history."""

    def __init__(self, from_shadow: bool = False) -> None:
        self.from_shadow = from_shadow  # values come from a ShadowTap, else from the points
        self.values: dict[tuple[int, str, int], RegisterValue] = {}
        self._pending: dict[int, tuple[str | None, list]] = {}
        self.version = 0  # bumped on every update

    def frame(self, f: Frame) -> None:
        """Points mode: what the decoders would have put into the shadow for this frame."""
        if self.from_shadow or f.unit is None or f.protocol == "noise":
            return
        if f.crc_ok is False or f.exception:
            if f.pair is not None:
                self._pending.pop(f.pair, None)
            return
        table, pts = _commit_points(f, self._pending)
        if table is None:
            return
        for p in pts:
            a = p.get("address")
            if a is not None:
                self.set(f.unit, table, a, p.get("raw"), p, f.t_ns)

    def shadow(self, unit: int, t_ns: int, entries) -> None:
        """Shadow mode: entries from ShadowTap.observe / sweep."""
        values = self.values
        for table, a, raw, p in entries:
            rv = values.get((unit, table, a))
            if rv is not None and p is not None and rv.raw == raw:  # seen again, unchanged (most polls)
                v = p.get("value", raw)
                rv.value, rv.eng_unit, rv.text, rv.t_ns = v, p.get("unit"), p.get("text") or "", t_ns
                if type(v) in _NUMBER:
                    rv.history.append(v)
                continue
            self.set(unit, table, a, raw, p, t_ns)
        self.version += 1

    def set(self, unit: int, table: str, addr: int, raw, p: dict | None, t_ns: int) -> None:
        key = (unit, table, addr)
        rv = self.values.get(key)
        if rv is None:
            rv = self.values[key] = RegisterValue(unit, table, addr, f"{table}[{addr}]", raw, raw, None, "", t_ns, t_ns)
        elif rv.raw != raw:
            rv.changed_ns = t_ns
            rv.changes += 1
        if p is not None:
            rv.name = p.get("name") or rv.name
            rv.id = p.get("id") or ""
            rv.value, rv.eng_unit, rv.text = p.get("value", raw), p.get("unit"), p.get("text") or ""
            if type(rv.value) in _NUMBER:
                rv.history.append(rv.value)
        elif rv.raw != raw:  # no decoded point for this value: show the number the shadow holds
            rv.value, rv.eng_unit, rv.text = raw, None, ""
        rv.raw, rv.t_ns = raw, t_ns
        self.version += 1

    def rows(self, unit: int | None = None) -> list[RegisterValue]:
        keys = sorted(k for k in self.values if unit is None or k[0] == unit)
        return [self.values[k] for k in keys]
