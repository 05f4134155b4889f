"""The change log of one register: its value changes (time, frame, old -> new with the unit), not every
sample; Enter (or a click on the selected line) on one goes to its frame.

The changes are the register history's samples flagged as changes (history.py):
every change while the register has fewer samples than the cap, and after
thinning those it kept (a change whose predecessors were thinned out says so).
The list is a vlist.CursorList (only the lines on screen are formatted) over the
positions of those samples, extended as samples arrive, so a register with
thousands of changes costs nothing until they scroll into view.
"""

from __future__ import annotations

import bisect
from array import array
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.binding import Binding

from sniffer.tui.framelist import S_CURSOR
from sniffer.tui.plot import JumpToFrame, number
from sniffer.analysis.register_book import RegisterValue
from sniffer.tui.vlist import CursorList

S_THINNED = Style(color="grey62", italic=True)


class ChangeLog(CursorList):
    """The changes of `register` (set with `show`), the latest followed until the cursor moves up."""

    BINDINGS: ClassVar[list[Binding]] = [*CursorList.BINDINGS, Binding("enter", "jump", "Go to frame")]
    DEFAULT_CSS = "ChangeLog { height: 1fr; overflow-x: hidden; } ChangeLog:focus { background: $boost; }"

    def __init__(self, store, **kw) -> None:
        super().__init__(store, **kw)
        self.register: RegisterValue | None = None
        self.changes = array("q")  # history positions of the changes, in time order
        self._synced: tuple | None = None  # (register key, thins, settled position, samples seen)

    # ------------------------------------------------------------ data
    def positions(self):
        return self.changes

    def may_follow(self) -> bool:
        return True  # the register's history goes on while the view is paused

    def virtual_width(self) -> int:
        return self.size.width

    def show(self, rv: RegisterValue | None) -> bool:
        """Show `rv`'s changes (again: only what arrived or was rewritten since); True if anything changed."""
        s = None if rv is None else rv.history
        state = None if s is None else ((rv.unit, rv.table, rv.address), s.thins, s.settled, s.seen)
        old = self._synced
        if state == old and rv is self.register:
            return False
        if s is None or old is None or old[:2] != state[:2] or rv is not self.register:
            self.changes = array("q", s.change_positions() if s is not None else ())
            self.follow = True  # another register (or thinned again): its latest change
        else:  # samples from the open bucket on may have been rewritten since: listed again
            del self.changes[bisect.bisect_left(self.changes, old[2]):]
            self.changes.extend(s.change_positions(old[2]))
        self.register = rv
        self._synced = state
        self.refresh_rows()
        return True

    def change(self, line: int) -> tuple[int, int, float | None, float, bool]:
        """(t_ns, frame index, old value, new value, thinned before) of a line."""
        return self.register.history.change(self.changes[line])

    def line_text(self, pos: int) -> Text:
        t, ix, old, new, thinned = self.change(pos)
        unit = self.register.eng_unit or ""
        text = Text(f"{self.store.time.text(t):>12}  #{ix:<8} ", no_wrap=True, overflow="ellipsis")
        text.append(f"{'first' if old is None else number(old)} → {number(new)} {unit}".rstrip())
        if thinned:
            text.append("  (changes before it thinned out)", S_THINNED)
        if pos == self.cursor:
            text.stylize(S_CURSOR)
        return text

    # ------------------------------------------------------------ keys
    def action_jump(self) -> None:
        if 0 <= self.cursor < self.count():
            self.post_message(JumpToFrame(self.change(self.cursor)[1]))

    def on_click(self, event) -> None:
        pos = self.clicked_pos(event)
        if pos is not None and pos == self.cursor:  # a click on the selected line goes to its frame
            self.action_jump()
        elif pos is not None:
            self._move_to(pos)
