"""A virtual list with a cursor: a Line-API ScrollView that formats only the rows on screen (like toolong).

The frame list and the transaction list are both this: `count()` rows, `line_text(pos)` for one of
them, a cursor moved by the keys or a click, and a list that follows the tail until the user moves
up (End or G follows again).
"""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.binding import Binding
from textual.geometry import Size
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip


class CursorList(ScrollView, can_focus=True):
    """Rows are positions 0..count()-1; `cursor` is one of them (-1: none)."""

    BINDINGS: ClassVar[list[Binding]] = [
        Binding("up,k", "cursor(-1)", "Up", show=False),
        Binding("down,j", "cursor(1)", "Down", show=False),
        Binding("pageup", "page(-1)", "PgUp", show=False),
        Binding("pagedown", "page(1)", "PgDn", show=False),
        Binding("home", "first", "First", show=False),
        Binding("end,G", "last", "Tail", show=False),
    ]

    cursor = reactive(-1, always_update=True, repaint=False)

    def __init__(self, store, **kw) -> None:
        super().__init__(**kw)
        self.store = store  # a FrameStore: what the rows show
        self.follow = True

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

    # ---- data
    def refresh_rows(self) -> None:
        """Called after the rows changed."""
        n = self.count()
        self.virtual_size = Size(max(self.size.width, 200), n)
        if self.follow and n:
            if self.cursor != n - 1:
                self.cursor = n - 1
            self.scroll_end(animate=False, immediate=True)
        elif self.cursor >= n:
            self.cursor = n - 1
        self.refresh()

    def on_resize(self, event) -> None:
        if self.follow and self.count():  # shown for the first time (a tab opened): the tail is in view
            self.scroll_end(animate=False, immediate=True)

    def watch_cursor(self, old: int, new: int) -> None:
        if new >= 0:
            self.scroll_to_region_visible(new)
        self.refresh()
        self.cursor_moved()

    def scroll_to_region_visible(self, pos: int) -> None:
        top = round(self.scroll_offset.y)
        h = max(self.scrollable_content_region.height, 1)
        if pos < top:
            self.scroll_to(y=pos, animate=False, immediate=True)
        elif pos >= top + h:
            self.scroll_to(y=pos - h + 1, animate=False, immediate=True)

    # ---- actions
    def _move_to(self, pos: int) -> None:
        n = self.count()
        if not n:
            return
        pos = max(0, min(n - 1, pos))
        self.follow = pos == n - 1 and self.may_follow()
        self.cursor = pos

    def action_cursor(self, delta: int) -> None:
        self._move_to(self.cursor + delta)

    def action_page(self, direction: int) -> None:
        self._move_to(self.cursor + direction * max(self.scrollable_content_region.height - 1, 1))

    def action_first(self) -> None:
        self._move_to(0)

    def action_last(self) -> None:
        self._move_to(self.count() - 1)
        self.follow = True

    def on_mouse_scroll_up(self, event) -> None:
        self.follow = False  # reading back: stop following the tail

    def clicked_pos(self, event) -> int | None:
        pos = round(self.scroll_offset.y) + event.y
        return pos if 0 <= pos < self.count() else None

    def on_click(self, event) -> None:
        pos = self.clicked_pos(event)
        if pos is not None:
            self._move_to(pos)

    # ---- Line API
    def render_line(self, y: int) -> Strip:
        scroll_x, scroll_y = self.scroll_offset
        pos = scroll_y + y
        width = self.scrollable_content_region.width
        if pos >= self.count() or pos < 0:
            return Strip.blank(width, self.rich_style)
        segments = [s for s in self.line_text(pos).render(self.app.console) if s.text != "\n"]
        return Strip(segments).crop_extend(scroll_x, scroll_x + width, self.rich_style)
