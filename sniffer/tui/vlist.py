"""A virtual list with a cursor: a Line-API ScrollView that formats only the rows on screen (like toolong).

The frame list and the transaction list are both this: `positions()` shown a row each, `line_text(pos)`
for one of them, a cursor moved by the keys or a click, and a list that follows the tail until the
user moves up (End or G follows again).  A list may draw `header_lines` lines of its own above the
rows (`header_strip`), which do not scroll.
"""

from __future__ import annotations

import time
from typing import ClassVar

from rich.text import Text
from textual.binding import Binding
from textual.geometry import Size
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip

TAIL_EVERY_S = 0.2  # a fast tail (more than TAIL_ROWS new rows since the last draw) is drawn at most this often
TAIL_ROWS = 4

# moving in a long list (the frame list, the transactions, the byte view): each has the actions cursor, page,
# first and last
MOVE_KEYS = (
    Binding("up,k", "cursor(-1)", "Up", show=False),
    Binding("down,j", "cursor(1)", "Down", show=False),
    Binding("pageup", "page(-1)", "PgUp", show=False),
    Binding("pagedown", "page(1)", "PgDn", show=False),
    Binding("home", "first", "First", show=False),
    Binding("end,G", "last", "Tail", show=False),
)


class CursorList(ScrollView, can_focus=True):
    """Rows are positions 0..count()-1; `cursor` is one of them (-1: none)."""

    BINDINGS: ClassVar[list[Binding]] = [*MOVE_KEYS]
    header_lines = 0  # lines drawn above the rows by header_strip

    cursor = reactive(-1, always_update=True, repaint=False)

    def __init__(self, store, **kw) -> None:
        super().__init__(**kw)
        self.store = store  # a FrameStore: what the rows show
        self.follow = True
        self.tailing = False  # the cursor moves because rows arrived (refresh_rows), not by the user
        self._tail_drawn_at = float("-inf")

    # ---- what a subclass says
    def positions(self):
        """The sequence shown (one item a row): the store's view of rows, of transactions."""
        raise NotImplementedError

    def count(self) -> int:
        return len(self.positions())

    @property
    def selected(self):
        """The item at the cursor, or None."""
        v = self.positions()
        return v[self.cursor] if 0 <= self.cursor < len(v) else None

    def line_text(self, pos: int) -> Text:
        """Row `pos` (0 <= pos < count()), styled, the cursor's highlight included."""
        raise NotImplementedError

    def may_follow(self) -> bool:
        """Whether the cursor on the last row follows new rows (a paused view does not)."""
        return not self.store.paused

    def cursor_moved(self) -> None:
        """Called after every cursor change (a subclass posts its message)."""

    def header_strip(self, y: int, width: int) -> Strip:
        """Header line y (< header_lines)."""
        raise NotImplementedError

    def virtual_width(self) -> int:
        """How wide the rows may be (wider than the view: scrolled sideways)."""
        return max(self.size.width, 200)

    # ---- data
    def _fit(self) -> int:
        """The scrollable height made the rows' count (rows taken in since the last refresh count)."""
        n = self.count()
        if self.virtual_size.height != n + self.header_lines:
            self.virtual_size = Size(self.virtual_width(), n + self.header_lines)
        return n

    def tail_due(self, new_rows: int, every: float = TAIL_EVERY_S) -> bool:
        """Should `new_rows` rows that came since the last draw be drawn now?  Followed, a fast tail (more
        than TAIL_ROWS rows since the last draw) scrolls the whole window at every draw, a blur that costs a
        screen of rows each time (and the viewer's CPU is taken from the capture on a small machine): it is
        drawn at most every `every` seconds.  A slow tail, or a list that does not follow, now."""
        return (not self.follow or new_rows <= TAIL_ROWS
                or time.monotonic() - self._tail_drawn_at >= every)

    def refresh_rows(self, grown: bool = False) -> None:
        """Called after the rows changed; `grown`: only rows at the end came (below a window that does not
        follow the tail they change nothing on screen but the scroll extent)."""
        n = self.count()
        size = Size(self.virtual_width(), n + self.header_lines)
        if (grown and not self.follow and round(self.scroll_offset.y) + self.size.height <= self.virtual_size.height
                and hasattr(self, "_scroll_update")):  # Textual's own way to a new extent without a repaint
            self.set_reactive(CursorList.virtual_size, size)  # the rows on screen stay as they are
            self._scroll_update(size)
            return
        self.virtual_size = size
        self._tail_drawn_at = time.monotonic()
        if self.follow and n:
            if self.cursor != n - 1:
                self.tailing = True
                try:
                    self.cursor = n - 1
                finally:
                    self.tailing = False
            self.scroll_end(animate=False, immediate=True)
        elif self.cursor >= n:
            self.cursor = n - 1
        self.refresh()

    def on_resize(self, event) -> None:
        self.refresh_rows()  # shown for the first time (a tab opened): the tail comes into view

    @property
    def rows_shown(self) -> int:
        """How many rows fit under the header."""
        return max(self.scrollable_content_region.height - self.header_lines, 1)

    def watch_cursor(self, old: int, new: int) -> None:
        if new >= 0:
            self.scroll_to_region_visible(new)
        self.refresh()
        self.cursor_moved()

    def scroll_to_region_visible(self, pos: int) -> None:
        top = round(self.scroll_offset.y)  # the row under the header
        h = self.rows_shown
        if pos < top:
            self.scroll_to(y=pos, animate=False, immediate=True)
        elif pos >= top + h:
            self.scroll_to(y=pos - h + 1, animate=False, immediate=True)

    # ---- actions
    def _move_to(self, pos: int) -> None:
        n = self._fit()
        if not n:
            return
        pos = max(0, min(n - 1, pos))
        self.follow = pos == n - 1 and self.may_follow()
        self.cursor = pos

    def action_cursor(self, delta: int) -> None:
        self._move_to(self.cursor + delta)

    def action_page(self, direction: int) -> None:
        self._move_to(self.cursor + direction * max(self.rows_shown - 1, 1))

    def action_first(self) -> None:
        self._move_to(0)

    def action_last(self) -> None:
        self._move_to(self.count() - 1)
        self.follow = True

    def on_mouse_scroll_up(self, event) -> None:
        self.follow = False  # reading back: stop following the tail

    def clicked_pos(self, event) -> int | None:
        pos = round(self.scroll_offset.y) + event.y - self.header_lines
        return pos if event.y >= self.header_lines and 0 <= pos < self.count() else None

    def on_click(self, event) -> None:
        pos = self.clicked_pos(event)
        if pos is not None:
            self._move_to(pos)

    # ---- Line API
    def render_line(self, y: int) -> Strip:
        scroll_x, scroll_y = self.scroll_offset
        width = self.scrollable_content_region.width
        if y < self.header_lines:
            return self.header_strip(y, width)
        pos = scroll_y + y - self.header_lines
        if pos >= self.count() or pos < 0:
            return Strip.blank(width, self.rich_style)
        segments = [s for s in self.line_text(pos).render(self.app.console) if s.text != "\n"]
        return Strip(segments).crop_extend(scroll_x, scroll_x + width, self.rich_style)
