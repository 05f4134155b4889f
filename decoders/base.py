"""What a decoder is: a model id, the codes it may emit, and decode()."""

from __future__ import annotations

from typing import Protocol

from sniffer.codes import Code
from sniffer.frame import Frame


class UnitState:
    """Per-unit memory across frames: the register shadow and anything a model tracks.

    The shadow (holding, input, coils, discrete) is written only through
    `commit`, which records the same write on the frame (`Frame.writes`):
    what a viewer reads there is what the decoder keeps here.

    `version` counts the changes of what a decoder carries over into the next part of a
    capture (decoders/carry.py): a register that scales others (TDS-V8 Cn-02), a setting the
    traffic showed (`remember`).  A part cut now (a segment, a trigger window) starts with it.
    """

    __slots__ = ("unit", "holding", "input", "coils", "discrete", "extra", "tables", "version")

    def __init__(self, unit: int) -> None:
        self.unit = unit
        self.holding: dict[int, int] = {}
        self.input: dict[int, int] = {}
        self.coils: dict[int, int] = {}
        self.discrete: dict[int, int] = {}
        self.extra: dict = {}
        self.version = 0
        # the protocol's table words (sniffer.protocols.TABLES) -> the shadow dict
        self.tables: dict[str, dict[int, int]] = {
            "holding": self.holding, "input": self.input, "coil": self.coils, "discrete": self.discrete,
        }

    def commit(self, f: Frame, table: str, start: int, values: list[int]) -> None:
        """Put `values` (consecutive from address `start`) into the shadow and record them on `f`.

        `values` is kept, not copied, as the frame's record: the caller hands over a list
        nothing changes afterwards.
        """
        d = self.tables[table]
        if len(values) == 1:
            d[start] = values[0]
        else:
            d.update(zip(range(start, start + len(values)), values))
        f.writes.append([table, start, values])

    def remember(self, key: str, value) -> None:
        """extra[key] = value, counted in `version` when it changes (a setting carried over)."""
        if self.extra.get(key) != value:
            self.extra[key] = value
            self.version += 1

    def snapshot(self) -> dict[tuple[str, int], int]:
        """{(table, address): raw} of the whole shadow (tests compare it with what frames recorded)."""
        return {(t, a): v for t, d in self.tables.items() for a, v in d.items()}

    # ---- a part of a capture decoded ahead of the parts before it (sniffer.parallel) ----------------
    def dump(self) -> dict:
        """The unit's memory as plain data: {"holding": {addr: raw}, ..., "extra": {...}} (`load` takes it)."""
        return {name: {**getattr(d, "base", {}), **_own(d)}
                for name, d in (*self.tables.items(), ("extra", self.extra))}

    def load(self, d: dict) -> None:
        """Start from `dump()` of a unit (what it knew where a part of the capture starts)."""
        self._set({name: dict(d.get(name) or {}) for name in (*self.tables, "extra")})

    def track(self, reads: dict) -> None:
        """From now on writes land in fresh tables and a read of what the part has not written yet goes to
        the memory as it is now (a guess of what the unit knew at the cut), recorded in `reads`:
        {(unit, table, key): (known, value)}.  `written()` gives what the part wrote."""
        u = self.unit
        self._set({name: Overlay(dict(d), reads, (u, name))
                   for name, d in (*self.tables.items(), ("extra", self.extra))})

    def written(self) -> dict:
        """What was written since `track()`: {table or "extra": {key: final value}} (tables written to only)."""
        out = {}
        for name, d in (*self.tables.items(), ("extra", self.extra)):
            own = _own(d)
            if own:
                out[name] = own
        return out

    def _set(self, d: dict) -> None:
        self.holding, self.input, self.coils, self.discrete = d["holding"], d["input"], d["coil"], d["discrete"]
        self.extra = d["extra"]
        self.tables = {"holding": self.holding, "input": self.input, "coil": self.coils, "discrete": self.discrete}


def _own(d: dict) -> dict:
    """A table's own items (an Overlay's: what the part wrote, without its base)."""
    return {k: dict.__getitem__(d, k) for k in dict.keys(d)}


class Overlay(dict):
    """One table of a tracked unit (UnitState.track): its own items are what the part wrote; a read of any
    other key falls through to `base` and is recorded once, (known, value), in `reads` under `where` + key.

    Only reads go through Python (get, [], in); writes stay the plain dict's.  A decoder reads the shadow
    rarely (a register that scales others, a mask write's old value, a setting the traffic showed)."""

    __slots__ = ("base", "reads", "where")

    def __init__(self, base: dict, reads: dict, where: tuple) -> None:
        super().__init__()
        self.base, self.reads, self.where = base, reads, where

    def _fall(self, key):
        known = key in self.base
        value = self.base[key] if known else None
        self.reads.setdefault((*self.where, key), (known, value))
        return known, value

    def get(self, key, default=None):
        if dict.__contains__(self, key):
            return dict.__getitem__(self, key)
        known, value = self._fall(key)
        return value if known else default

    def __getitem__(self, key):
        if dict.__contains__(self, key):
            return dict.__getitem__(self, key)
        known, value = self._fall(key)
        if not known:
            raise KeyError(key)
        return value

    def __contains__(self, key) -> bool:
        return dict.__contains__(self, key) or self._fall(key)[0]


class Decoder(Protocol):
    model: str
    # the annotation codes it may emit, declared on the class (as sigrok's decoders declare their annotations):
    # decoders.registry.code_book() assembles the code table from the classes without loading a map
    codes: tuple[Code, ...]

    def decode(self, frame: Frame, request: Frame | None, state: UnitState) -> None:
        """Fill frame.points / fields / summary / exception / annotations / writes. Never raise.

        Every write to the unit's register shadow goes through `state.commit(frame, ...)`.
        """
