"""The `g` bar: one line docked on top where a frame number or a time is typed (goto.py reads it)."""

from __future__ import annotations

from typing import ClassVar

from textual.binding import Binding
from textual.widgets import Input

from sniffer.tui.goto import EXAMPLES


class GotoBar(Input):
    """Hidden until opened; Enter posts Input.Submitted (the App goes there), Esc closes it."""

    BINDINGS: ClassVar[list[Binding]] = [Binding("escape", "close", "Close", show=False)]
    DEFAULT_CSS = "GotoBar { dock: top; display: none; } GotoBar.shown { display: block; }"

    def __init__(self, **kw) -> None:
        super().__init__(placeholder=f"go to: {EXAMPLES}   (Enter goes, Esc closes)", **kw)

    @property
    def shown(self) -> bool:
        return self.has_class("shown")

    def open(self) -> None:
        self.value = ""
        self.add_class("shown")
        # focus now, not after the queued keys: what is typed right after `g` is the target, never commands
        self.screen.set_focus(self)

    def action_close(self) -> None:
        from sniffer.tui.framelist import FrameList

        self.remove_class("shown")
        self.screen.set_focus(self.screen.query_one(FrameList))
