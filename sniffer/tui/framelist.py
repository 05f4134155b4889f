"""The frame list: a virtual list (vlist.CursorList) over the store's view index (like toolong).

Only the rows on screen are formatted, so a million frames cost nothing until
they scroll into view.  The list follows the tail until the user moves up;
End (or G) follows again.
"""

from __future__ import annotations

from rich.style import Style
from rich.text import Text
from textual.message import Message

from ..frame import Frame
from .model import F_ERROR, F_EXC, F_FAULT, F_NOISE, F_TIMEOUT, F_WARN
from .vlist import CursorList

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


def row_mark(fl: int) -> str:
    """The two-character problem mark a row starts with (its colour is row_style's)."""
    if fl & F_ERROR:
        return "!!"
    if fl & F_EXC:
        return "E "
    if fl & F_FAULT:
        return "F "
    if fl & F_TIMEOUT:
        return "T "
    return "! " if fl & (F_WARN | F_NOISE) else "  "


def format_row(f: Frame, fl: int, t0_ns: int, marked: bool) -> Text:
    t = (f.t_ns - t0_ns) / 1e9
    mark = row_mark(fl)
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


class FrameList(CursorList):
    """Rows are positions in `store.view`; `cursor` is one of them."""

    DEFAULT_CSS = "FrameList { height: 1fr; }"

    class Selected(Message):
        def __init__(self, row: int | None) -> None:
            self.row = row
            super().__init__()

    def positions(self):
        return self.store.view

    def cursor_moved(self) -> None:
        self.post_message(self.Selected(self.selected_row))

    @property
    def selected_row(self) -> int | None:
        return self.selected

    def select_row(self, row: int) -> bool:
        pos = self.store.pos_of_row(row)
        if pos is None:
            return False
        self.follow = False
        self.cursor = pos
        return True

    def line_text(self, pos: int) -> Text:
        store = self.store
        row = store.view[pos]
        text = format_row(store.frame(row), store.flags[row], store.t0_ns, row in store.bookmarks)
        sel = self.selected_row
        if pos == self.cursor:
            text.stylize(S_CURSOR)
        elif sel is not None and store.pair_row(row) == sel:
            text.stylize(S_PAIR)  # the selected frame's request / response
        return text
