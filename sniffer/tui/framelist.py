"""The frame list: a virtual list (vlist.CursorList) over the store's view index (like toolong).

Only the rows on screen are formatted, so a million frames cost nothing until
they scroll into view.  The list follows the tail until the user moves up;
End (or G) follows again.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from rich.style import Style
from rich.text import Text
from textual.message import Message
from textual.strip import Strip

from sniffer.frame import Frame
from sniffer.tui.store import F_ERROR, F_EXC, F_FAULT, F_NOISE, F_TIMEOUT, F_WARN
from sniffer.tui.timebase import TimeBase, delta_text
from sniffer.tui.vlist import CursorList

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
S_REF = Style(color="bright_blue", bold=True, reverse=True)  # the time reference's *REF*


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


MIN_SUMMARY = 20  # the summary keeps at least this many characters: narrower lists drop columns first


@dataclass(frozen=True)
class Column:
    key: str
    title: str
    width: int
    right: bool = False  # right-aligned
    drop: int = 0  # 0: always shown; else dropped in this order (1 first) when the summary would be too narrow


@dataclass(frozen=True)
class Layout:
    """The frame list's columns at one width: which are shown, how wide, and the header line."""

    columns: tuple[Column, ...]
    summary: int  # characters left for the summary
    header: str

    def has(self, key: str) -> bool:
        return any(c.key == key for c in self.columns)


def fit_columns(width: int, tb: TimeBase, first_ns: int, last_ns: int, last_index: int, link: int = 0) -> Layout:
    """The columns that fit `width` (each followed by a space), the summary getting what is left.

    Widths follow the capture (the time column as wide as its times, the frame numbers as long as
    the last one's); below MIN_SUMMARY characters for the summary the least useful columns go first:
    the model (the detail and Units show it), the function code (the summary names it), Δt, latency.
    `link` > 0: a capture of several links, whose names are up to that long: a link column after the time.
    """
    digits = len(str(max(last_index, 0)))
    cols = [Column("mark", "", 3), Column("time", tb.title(), tb.width(first_ns, last_ns), right=True),
            Column("dt", "Δt", 8, right=True, drop=3), *([Column("link", "link", min(link, 12))] if link else []),
            Column("dir", "dir", 5), Column("unit", "unit", 4),
            Column("model", "model", 8, drop=1), Column("fc", "fc", 4, drop=2),
            Column("pair", "frame→pair", 2 * digits + 3), Column("lat", "latency", 8, right=True, drop=4)]
    cols = [Column(c.key, c.title, max(c.width, len(c.title)), c.right, c.drop) for c in cols]
    for drop in range(1, 5):
        if width - sum(c.width + 1 for c in cols) >= MIN_SUMMARY:
            break
        cols = [c for c in cols if c.drop != drop]
    summary = max(width - sum(c.width + 1 for c in cols), 0)
    head = " ".join(c.title.rjust(c.width) if c.right else c.title.ljust(c.width) for c in cols)
    head += f" summary [problems]   {tb.describe()}"
    return Layout(tuple(cols), summary, head[:width])


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


def summary_text(f: Frame) -> str:
    """The summary column's text: the decoder's summary, a bad CRC and the problems' codes; a noise frame's bytes."""
    if f.protocol == "noise":
        return f"{len(f.raw)}B {f.raw[:16].hex(' ')}  [{f.noise_reason}]"
    summary = f.summary
    if f.crc_ok is False:
        summary = "CRC! " + summary
    notes = [a.code for a in f.annotations if a.severity != "info"]
    if notes:
        summary += "  [" + ", ".join(notes) + "]"
    return summary


def format_row(f: Frame, fl: int, lay: Layout, tb: TimeBase, marked: bool, is_ref: bool = False,
               prev_t_ns: int | None = None) -> Text:
    """One line of the list in `lay`'s columns; `prev_t_ns` is the previous shown frame's time (Δt)."""
    cells = {
        "mark": ("*" if marked else " ") + row_mark(fl),
        "time": "*REF*" if is_ref else tb.text(f.t_ns),
        "dt": "" if prev_t_ns is None else delta_text(f.t_ns - prev_t_ns),
        "dir": ROLE_TAG.get(f.role, " ??? "),
        "unit": "u  -" if f.unit is None else f"u{f.unit:3d}",
        "model": (f.model or "")[:8],
        "fc": "fc--" if f.function is None else f"fc{f.function:02X}",
        "pair": f"#{f.index}" + (f"{'→' if f.role == 'request' else '←'}#{f.pair}" if f.pair is not None else ""),
        "link": f.link[:12],
        "lat": f"{f.latency_ms:6.1f}ms" if f.latency_ms is not None and f.role == "response" else "",
    }
    styles = {"dir": S_REQ if f.role == "request" else S_RSP if f.role == "response" else None,
              "time": S_REF if is_ref else None}
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append("*" if marked else " ", S_MARK)
    plain = [cells["mark"][1:], " "]  # runs without a style of their own go in as one piece (fewer spans)
    for c in lay.columns[1:]:
        cell = cells[c.key].rjust(c.width) if c.right else cells[c.key].ljust(c.width)
        style = styles.get(c.key)
        if style is None:
            plain += (cell, " ")
        else:
            text.append("".join(plain))
            text.append(cell, style)
            plain = [" "]
    plain.append(summary_text(f))
    text.append("".join(plain))
    st = row_style(fl)
    if st is not None:
        text.stylize(st, 1)
    text.truncate(sum(c.width + 1 for c in lay.columns) + lay.summary, overflow="ellipsis")
    return text


class FrameList(CursorList):
    """Rows are positions in `store.view`; `cursor` is one of them.  The first line is the header, drawn
    with the rows (so it always names their columns and time base); rows start on the second."""

    COMPONENT_CLASSES: ClassVar[set[str]] = {"framelist--header"}
    # rows fit the width: nothing to scroll to sideways
    DEFAULT_CSS = """
    FrameList { height: 1fr; overflow-x: hidden; }
    FrameList > .framelist--header { color: $text-muted; text-style: bold; }
    """
    header_lines = 1

    class Selected(Message):
        def __init__(self, row: int | None, following: bool = False) -> None:
            self.row = row
            self.following = following  # moved by new frames at the tail, not by the user
            super().__init__()

    def __init__(self, store, **kw) -> None:
        super().__init__(store, **kw)
        self._extent = (0, 0, 0, 0)  # (first t_ns, last t_ns, last frame number, link names' width): what
        # the column widths fit
        self._layout: tuple[tuple, Layout] | None = None  # (what it was fitted to, the layout)

    def positions(self):
        return self.store.view

    def cursor_moved(self) -> None:
        self.post_message(self.Selected(self.selected_row, self.tailing))

    def virtual_width(self) -> int:
        return self.scrollable_content_region.width

    # ---- data
    def refresh_rows(self, grown: bool = False) -> None:
        """Called by the App after the store changed (`grown`: CursorList.refresh_rows)."""
        store = self.store
        if len(store):
            columns = self.layout_columns() if grown else None
            self._extent = (store.t_ns[0], store.last_t_ns, store.frame(len(store) - 1).index, store.link_width)
            grown = grown and self.layout_columns() == columns  # columns refitted: every row on screen changes
        super().refresh_rows(grown)

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

    # ---- columns
    def layout_columns(self) -> Layout:
        """The columns for the current width and time base (fitted again when either changed)."""
        width = self.scrollable_content_region.width
        key = (width, self.store.time.version, self._extent)
        if self._layout is None or self._layout[0] != key:
            self._layout = (key, fit_columns(width, self.store.time, *self._extent))
        return self._layout[1]

    # ---- Line API
    def header_strip(self, y: int, width: int) -> Strip:
        head = Text(self.layout_columns().header, no_wrap=True, end="")
        return Strip(head.render(self.app.console), head.cell_len).crop_extend(
            0, width, self.get_component_rich_style("framelist--header"))

    def line_text(self, pos: int) -> Text:
        store = self.store
        row = store.view[pos]
        tb = store.time
        text = format_row(store.frame(row), store.flags[row], self.layout_columns(), tb, row in store.bookmarks,
                          row == tb.ref_row, store.t_ns[store.view[pos - 1]] if pos else None)
        sel = self.selected_row
        if pos == self.cursor:
            text.stylize(S_CURSOR)
        elif sel is not None and store.pair_row(row) == sel:
            text.stylize(S_PAIR)  # the selected frame's request / response
        return text
