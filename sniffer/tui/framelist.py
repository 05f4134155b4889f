"""The frame list: a Line-API ScrollView over the store's view index (like toolong).

Only the rows on screen are formatted, so a million frames cost nothing until
they scroll into view.  The list follows the tail until the user moves up;
End (or G) follows again.
"""

from __future__ import annotations

from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.binding import Binding
from textual.geometry import Size
from textual.message import Message
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip

from ..frame import Frame
from .model import F_ERROR, F_EXC, F_FAULT, F_NOISE, F_TIMEOUT, F_WARN, FrameStore

ROLE_TAG = {"request": "->REQ", "response": "<-RSP", "unknown": " ??? ", "noise": "NOISE"}
S_ERROR = Style(color="bright_red", bold=True)
S_EXC = Style(color="magenta", bold=True)
S_FAULT = Style(color="dark_orange", bold=True)  # the drive tripped or warns
S_TIMEOUT = Style(color="yellow")
S_WARN = Style(color="yellow")
S_NOISE = Style(color="grey50", italic=True)
S_REQ = Style(color="cyan")
S_RSP = Style(color="green")
S_CURSOR = Style(bgcolor="grey30", bold=True)
S_PAIR = Style(bgcolor="grey19")
S_MARK = Style(color="bright_blue", bold=True)


def row_style(fl: int) -> Style | None:
    if fl & F_ERROR:
        return S_ERROR
    if fl & F_EXC:
        return S_EXC
    if fl & F_FAULT:
        return S_FAULT
    if fl & F_NOISE:
        return S_NOISE
    if fl & (F_TIMEOUT | F_WARN):
        return S_WARN
    return None


def format_row(f: Frame, fl: int, t0_ns: int, marked: bool) -> Text:
    t = (f.t_ns - t0_ns) / 1e9
    if fl & F_ERROR:
        mark = "!!"
    elif fl & F_EXC:
        mark = "E "
    elif fl & F_FAULT:
        mark = "F "
    elif fl & F_TIMEOUT:
        mark = "T "
    else:
        mark = "! " if fl & (F_WARN | F_NOISE) else "  "
    role = ROLE_TAG.get(f.role, " ??? ")
    unit = "  -" if f.unit is None else f"{f.unit:3d}"
    model = (f.model or "")[:8]
    fc = "--" if f.function is None else f"{f.function:02X}"
    link = f"#{f.index}" + (f"{'→' if f.role == 'request' else '←'}#{f.pair}" if f.pair is not None else "")
    lat = f"{f.latency_ms:7.1f}ms" if f.latency_ms is not None and f.role == "response" else " " * 9
    if f.protocol == "noise":
        summary = f"{len(f.raw)}B {f.raw[:16].hex(' ')}  [{f.noise_reason}]"
    else:
        summary = f.summary
        if f.crc_ok is False:
            summary = "CRC! " + summary
        notes = [a.code for a in f.annotations if a.severity != "info"]
        if notes:
            summary += "  [" + ", ".join(notes) + "]"
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append("*" if marked else " ", S_MARK)
    text.append(f"{mark}{t:12.6f} ")
    text.append(f"{role} ", S_REQ if f.role == "request" else S_RSP if f.role == "response" else None)
    text.append(f"u{unit} {model:<8} fc{fc} {link:<14} {lat} {summary}")
    st = row_style(fl)
    if st is not None:
        text.stylize(st, 1)
    return text


# moving in a long list (the frame list, the byte view): each has the actions cursor, page, first and last
MOVE_KEYS = (
    Binding("up,k", "cursor(-1)", "Up", show=False),
    Binding("down,j", "cursor(1)", "Down", show=False),
    Binding("pageup", "page(-1)", "PgUp", show=False),
    Binding("pagedown", "page(1)", "PgDn", show=False),
    Binding("home", "first", "First", show=False),
    Binding("end,G", "last", "Tail", show=False),
)


class FrameList(ScrollView, can_focus=True):
    """Rows are positions in `store.view`; `cursor` is one of them."""

    BINDINGS: ClassVar[list[Binding]] = [*MOVE_KEYS]
    DEFAULT_CSS = "FrameList { height: 1fr; }"

    cursor = reactive(-1, always_update=True, repaint=False)

    class Selected(Message):
        def __init__(self, row: int | None) -> None:
            self.row = row
            super().__init__()

    def __init__(self, store: FrameStore, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self.follow = True
        self._seen_generation = -1

    # ---- data
    def refresh_rows(self) -> None:
        """Called by the App after the store changed."""
        n = len(self.store.view)
        self.virtual_size = Size(max(self.size.width, 200), n)
        if self.follow and n:
            if self.cursor != n - 1:
                self.cursor = n - 1
            self.scroll_end(animate=False, immediate=True)
        elif self.cursor >= n:
            self.cursor = n - 1
        self.refresh()

    @property
    def selected_row(self) -> int | None:
        v = self.store.view
        return v[self.cursor] if 0 <= self.cursor < len(v) else None

    def select_row(self, row: int) -> bool:
        pos = self.store.pos_of_row(row)
        if pos is None:
            return False
        self.follow = False
        self.cursor = pos
        return True

    def watch_cursor(self, old: int, new: int) -> None:
        if new >= 0:
            self.scroll_to_region_visible(new)
        self.refresh()
        self.post_message(self.Selected(self.selected_row))

    def scroll_to_region_visible(self, pos: int) -> None:
        top = round(self.scroll_offset.y)
        h = max(self.scrollable_content_region.height, 1)
        if pos < top:
            self.scroll_to(y=pos, animate=False, immediate=True)
        elif pos >= top + h:
            self.scroll_to(y=pos - h + 1, animate=False, immediate=True)

    # ---- actions
    def _move_to(self, pos: int) -> None:
        n = len(self.store.view)
        if not n:
            return
        pos = max(0, min(n - 1, pos))
        self.follow = pos == n - 1 and not self.store.paused
        self.cursor = pos

    def action_cursor(self, delta: int) -> None:
        self._move_to(self.cursor + delta)

    def action_page(self, direction: int) -> None:
        self._move_to(self.cursor + direction * max(self.scrollable_content_region.height - 1, 1))

    def action_first(self) -> None:
        self._move_to(0)

    def action_last(self) -> None:
        self._move_to(len(self.store.view) - 1)
        self.follow = True

    def on_mouse_scroll_up(self, event) -> None:
        self.follow = False  # reading back: stop following the tail

    def on_click(self, event) -> None:
        pos = round(self.scroll_offset.y) + event.y
        if 0 <= pos < len(self.store.view):
            self._move_to(pos)

    # ---- Line API
    def render_line(self, y: int) -> Strip:
        scroll_x, scroll_y = self.scroll_offset
        pos = scroll_y + y
        width = self.scrollable_content_region.width
        store = self.store
        if pos >= len(store.view) or pos < 0:
            return Strip.blank(width, self.rich_style)
        row = store.view[pos]
        text = format_row(store.frame(row), store.flags[row], store.t0_ns, row in store.bookmarks)
        sel = self.selected_row
        if pos == self.cursor:
            text.stylize(S_CURSOR)
        elif sel is not None and store.pair_row(row) == sel:
            text.stylize(S_PAIR)  # the selected frame's request / response
        segments = list(text.render(self.app.console))
        segments = [s for s in segments if s.text != "\n"]
        return Strip(segments).crop_extend(scroll_x, scroll_x + width, self.rich_style)
