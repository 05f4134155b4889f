"""The change log of one register: its value changes (time, frame, old -> new with the unit), not every
sample; Enter on one goes to its frame.

The changes are the register history's samples flagged as changes (history.py):
every change while the register has fewer samples than the cap, and after
thinning those it kept (a change whose predecessors were thinned out says so).
The list is a Line-API view (only the lines on screen are formatted) over the
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
from textual.geometry import Size
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip

from .framelist import MOVE_KEYS, S_CURSOR
from .plot import JumpToFrame, number
from .shadow import RegisterValue

S_THINNED = Style(color="grey62", italic=True)


class ChangeLog(ScrollView, can_focus=True):
    """The changes of `register` (set with `show`); `cursor` is a line, -1 for none."""

    BINDINGS: ClassVar[list[Binding]] = [*MOVE_KEYS, Binding("enter", "jump", "Go to frame")]
    DEFAULT_CSS = "ChangeLog { height: 1fr; overflow-x: hidden; } ChangeLog:focus { background: $boost; }"

    cursor = reactive(-1, repaint=False)

    def __init__(self, t0_ns: int = 0, **kw) -> None:
        super().__init__(**kw)
        self.t0_ns = t0_ns
        self.register: RegisterValue | None = None
        self.positions = array("q")  # history positions of the changes, in time order
        self._synced: tuple | None = None  # (register key, thins, settled position, samples seen)

    # ------------------------------------------------------------ data
    def show(self, rv: RegisterValue | None, t0_ns: int) -> bool:
        """Show `rv`'s changes (again: only what arrived or was rewritten since); True if anything changed."""
        self.t0_ns = t0_ns
        key = None if rv is None else (rv.unit, rv.table, rv.address)
        s = None if rv is None else rv.history
        old = self._synced
        if s is None:
            state = None
        else:
            state = (key, s.thins, s.settled, s.seen)
        if state == old and rv is self.register:
            return False
        at_end = self.cursor < 0 or self.cursor >= len(self.positions) - 1
        if s is None or old is None or old[0] != key or old[1] != s.thins or rv is not self.register:
            self.positions = array("q", s.change_positions() if s is not None else ())
        else:  # samples from the open bucket on may have been rewritten since: listed again
            cut = bisect.bisect_left(self.positions, old[2])
            del self.positions[cut:]
            self.positions.extend(s.change_positions(old[2]))
        self.register = rv
        self._synced = state
        n = len(self.positions)
        self.virtual_size = Size(self.size.width, n)
        if at_end or self.cursor >= n:
            self.cursor = n - 1
            self.scroll_end(animate=False, immediate=True)
        self.refresh()
        return True

    def change(self, line: int) -> tuple[int, int, float | None, float, bool]:
        """(t_ns, frame index, old value, new value, thinned before) of a line."""
        return self.register.history.change(self.positions[line])

    # ------------------------------------------------------------ keys
    def action_cursor(self, step: int) -> None:
        n = len(self.positions)
        if n:
            self.cursor = max(0, min(n - 1, (self.cursor if self.cursor >= 0 else n - 1) + step))

    def action_page(self, direction: int) -> None:
        self.action_cursor(direction * max(self.scrollable_content_region.height - 1, 1))

    def action_first(self) -> None:
        self.action_cursor(-len(self.positions))

    def action_last(self) -> None:
        self.action_cursor(len(self.positions))

    def watch_cursor(self, line: int) -> None:
        if line >= 0:
            top, h = round(self.scroll_offset.y), max(self.scrollable_content_region.height, 1)
            if not top <= line < top + h:
                self.scroll_to(y=line if line < top else line - h + 1, animate=False, immediate=True)
        self.refresh()

    def action_jump(self) -> None:
        if 0 <= self.cursor < len(self.positions):
            self.post_message(JumpToFrame(self.change(self.cursor)[1]))

    def on_click(self, event) -> None:
        line = round(self.scroll_offset.y) + event.y
        if 0 <= line < len(self.positions):
            self.cursor = line

    # ------------------------------------------------------------ Line API
    def render_line(self, y: int) -> Strip:
        line = round(self.scroll_offset.y) + y
        width = self.scrollable_content_region.width
        if not 0 <= line < len(self.positions):
            return Strip.blank(width, self.rich_style)
        t, ix, old, new, thinned = self.change(line)
        unit = self.register.eng_unit or ""
        text = Text(f"{(t - self.t0_ns) / 1e9:11.3f} s  #{ix:<8} ", no_wrap=True, overflow="ellipsis")
        text.append(f"{'first' if old is None else number(old)} → {number(new)} {unit}".rstrip())
        if thinned:
            text.append("  (changes before it thinned out)", S_THINNED)
        if line == self.cursor:
            text.stylize(S_CURSOR)
        segments = [s for s in text.render(self.app.console) if s.text != "\n"]
        return Strip(segments).crop_extend(0, width, self.rich_style).apply_style(self.rich_style)
