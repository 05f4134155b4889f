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


class Decoder(Protocol):
    model: str
    # the annotation codes it may emit, declared on the class (as sigrok's decoders declare their annotations):
    # decoders.registry.code_book() assembles the code table from the classes without loading a map
    codes: tuple[Code, ...]

    def decode(self, frame: Frame, request: Frame | None, state: UnitState) -> None:
        """Fill frame.points / fields / summary / exception / annotations / writes. Never raise.

        Every write to the unit's register shadow goes through `state.commit(frame, ...)`.
        """
