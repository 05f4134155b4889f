"""What a decoder is: a model id, the codes it may emit, and decode()."""

from __future__ import annotations

from typing import Protocol

from sniffer.codes import Code
from sniffer.frame import Frame


class UnitState:
    """Per-unit memory across frames: the register shadow and anything a model tracks."""

    __slots__ = ("unit", "holding", "input", "coils", "discrete", "extra")

    def __init__(self, unit: int) -> None:
        self.unit = unit
        self.holding: dict[int, int] = {}
        self.input: dict[int, int] = {}
        self.coils: dict[int, int] = {}
        self.discrete: dict[int, int] = {}
        self.extra: dict = {}


class Decoder(Protocol):
    model: str
    codes: tuple[Code, ...]

    def decode(self, frame: Frame, request: Frame | None, state: UnitState) -> None:
        """Fill frame.points / fields / summary / exception / annotations. Never raise."""
