"""The Transactions tab: one line per request and its answer, and the latency histogram of a unit.

The list is a virtual list (vlist.CursorList) over `store.transactions.view`: only the lines on
screen are made, from their frames.  The frame filter applies (a transaction shows when its request
or its response passes it), the header says so.  Enter (or a click on the selected line) opens the
transaction's request in the Frames tab; the histogram shows the selected transaction's unit, or
all units while the list follows the tail or after `h`; `n` / `N` move to the next / previous
transaction with a problem.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.message import Message
from textual.widgets import Static

from decoders.registry import code_book
from sniffer import codes
from sniffer.frame import Frame, unit_key
from sniffer.tui.framelist import S_CURSOR, row_mark, row_style
from sniffer.tui.latency import BAR_ROWS, histogram_text
from sniffer.tui.store import F_PROBLEM, FrameStore
from sniffer.tui.transactions import BROADCAST, EXCEPTION, KIND_TEXT, PENDING, UNANSWERED
from sniffer.tui.vlist import CursorList

VALUES = 6  # values shown of a read's answer


@dataclass(frozen=True)
class Columns:
    """What fits a width: the time column's width (the store's time base: since the start, wall clock, from
    the reference), the model column or not, how wide the asked and answer columns are."""

    time: int = 12
    model: bool = True
    asked: int = 32
    answer: int = 38
    link: int = 0  # the link column's width (a capture of several links), 0: none


def fit_columns(width: int, time: int = 12, link: int = 0) -> Columns:
    """The columns for a width: the model goes under 110 characters, asked and answer share the rest (each
    within 12..48 and 12..60 characters; past that, the problems have the room).  `link` > 0: a link
    column that wide (up to 12) after the time."""
    link = min(max(link, 4), 12) if link else 0
    model = width >= 110
    rest = width - (3 + time + 1 + 5 + (9 if model else 0) + 5 + 10) - 3 - 1 - (link + 1 if link else 0)
    asked = min(max(rest * 4 // 9, 12), 48)
    return Columns(time, model, asked, min(max(rest - asked, 12), 60), link)


def header(time_title: str, cols: Columns) -> str:
    model = f"{'model':<8} " if cols.model else ""
    link = f"{'link':<{cols.link}} " if cols.link else ""
    return (f"   {time_title:>{cols.time}} {link}{'unit':4} {model}{'fc':4} {'latency':>9} {'asked':<{cols.asked}}   "
            f"{'answer':<{cols.answer}}  [problems]")
# what the answer column already says
_SAID = code_book().in_category(codes.TIMEOUT_CAT, codes.END_OF_CAPTURE_CAT, codes.ORPHAN_CAT)


def _clip(s: str, n: int) -> str:
    return s if len(s) <= n else s[:n - 1] + "…"


def _value(p: dict) -> str:
    v = p.get("value")
    shown = f"{v:g}" if isinstance(v, float) else str(v)
    return shown + (f" {p['unit']}" if p.get("unit") else "")


def answer_text(kind: int, req: Frame | None, rsp: Frame | None) -> str:
    """What came back: a read's values (short), a write's confirmation, the exception, or why nothing."""
    if kind in (PENDING, BROADCAST, *UNANSWERED):
        return KIND_TEXT[kind]
    if rsp is None:
        return "-"
    crc = "CRC! " if rsp.crc_ok is False else ""
    if kind == EXCEPTION and rsp.exception:
        code = rsp.exception.get("code")
        head = f"{code:02X}H " if isinstance(code, int) else ""
        return f"{crc}exception {head}{rsp.exception.get('name', '')}"
    pts = rsp.points
    if pts and req is not None and not req.points:  # the answer brought values the request did not carry
        more = f" … (+{len(pts) - VALUES})" if len(pts) > VALUES else ""
        return crc + ", ".join(_value(p) for p in pts[:VALUES]) + more
    return crc + rsp.summary


def asked_text(req: Frame | None, rsp: Frame | None) -> str:
    if req is None:
        if rsp is not None and rsp.pair is not None:
            return f"(request #{rsp.pair} not here)"
        return "(no request)"
    return ("CRC! " if req.crc_ok is False else "") + req.summary


def problems(frames) -> list[str]:
    out = []
    for f in frames:
        for a in f.annotations:
            if a.severity != "info" and a.code not in _SAID and a.code not in out:
                out.append(a.code)
    return out


def format_tx(store: FrameStore, tx: int, cols: Columns = Columns()) -> Text:
    txs = store.transactions
    req_row, rsp_row = txs.rows(tx)
    req = store.frame(req_row) if req_row >= 0 else None
    rsp = store.frame(rsp_row) if rsp_row >= 0 else None
    f0 = req if req is not None else rsp
    kind, fl = txs.kind[tx], txs.flags[tx]
    fc = "--" if f0.function is None else f"{f0.function & 0x7F:02X}"  # an exception answers its request's
    lat = rsp.latency_ms if rsp is not None and req is not None else None
    lat_s = f"{lat:7.1f}ms" if lat is not None else " " * 9
    notes = problems(f for f in (req, rsp) if f is not None)
    text = Text(no_wrap=True, overflow="ellipsis")
    model = f"{(f0.model or '')[:8]:<8} " if cols.model else ""
    link = f"{f0.link[:12]:<{cols.link}} " if cols.link else ""
    text.append(f" {row_mark(fl)}{store.time.text(f0.t_ns):>{cols.time}} {link}u{f0.unit:3d} {model}fc{fc} ")
    text.append(f"{lat_s} {_clip(asked_text(req, rsp), cols.asked):<{cols.asked}} → ")
    text.append(f"{_clip(answer_text(kind, req, rsp), cols.answer):<{cols.answer}}")
    if notes:
        text.append("  [" + ", ".join(notes) + "]")
    st = row_style(fl)
    if st is not None:
        text.stylize(st, 1)
    return text


class TransactionList(CursorList):
    """Positions in `store.transactions.view`; `cursor` is one of them."""

    BINDINGS: ClassVar[list[Binding]] = [
        Binding("enter", "choose", "Open frame", show=False),
        Binding("h", "all_units", "Histogram: all / this unit", show=False),
        Binding("n", "problem(1)", "Next problem", show=False),
        Binding("N", "problem(0)", "Prev problem", show=False),
    ]
    DEFAULT_CSS = "TransactionList { height: 1fr; }"

    class Highlighted(Message):
        def __init__(self, tx: int | None) -> None:
            self.tx = tx
            super().__init__()

    class Chosen(Message):
        """Open this transaction's request (or its response) in the Frames tab."""

        def __init__(self, tx: int) -> None:
            self.tx = tx
            super().__init__()

    def __init__(self, store: FrameStore, **kw) -> None:
        super().__init__(store, **kw)
        self.all_units = False  # the histogram shows every unit, not the selected transaction's

    def positions(self):
        return self.store.transactions.view

    def cursor_moved(self) -> None:
        self.post_message(self.Highlighted(self.selected_tx))

    @property
    def selected_tx(self) -> int | None:
        return self.selected

    def columns(self) -> Columns:
        store, tb = self.store, self.store.time
        time = max(tb.width(store.t_ns[0], store.last_t_ns) if len(store) else 8, len(tb.title()))
        return fit_columns(self.scrollable_content_region.width, time, store.link_width)

    def line_text(self, pos: int) -> Text:
        text = format_tx(self.store, self.store.transactions.view[pos], self.columns())
        if pos == self.cursor:
            text.stylize(S_CURSOR)
        return text

    def action_choose(self) -> None:
        tx = self.selected_tx
        if tx is not None:
            self.post_message(self.Chosen(tx))

    def on_click(self, event) -> None:
        pos = self.clicked_pos(event)
        if pos is not None and pos == self.cursor:  # a click on the selected line opens it
            self.action_choose()
        elif pos is not None:
            self._move_to(pos)

    def action_all_units(self) -> None:
        self.all_units = not self.all_units
        self.post_message(self.Highlighted(self.selected_tx))

    def action_problem(self, forward: int) -> None:
        view, flags = self.store.transactions.view, self.store.transactions.flags
        step = 1 if forward else -1
        pos = self.cursor + step
        while 0 <= pos < len(view):
            if flags[view[pos]] & F_PROBLEM:
                self._move_to(pos)
                return
            pos += step
        self.app.notify("no further problem transaction", timeout=2)


class TransactionsPane(Vertical):
    """Header (columns, what the filter does), the list, the histogram."""

    DEFAULT_CSS = """
    TransactionsPane > #txhead { height: 2; color: $text-muted; text-wrap: nowrap; text-overflow: clip; }
    TransactionsPane > TransactionList { height: 1fr; }
    TransactionsPane > #histogram { height: 10; border-top: solid $primary; padding: 0 1; text-wrap: nowrap;
                                    text-overflow: clip; }
    """

    def __init__(self, store: FrameStore, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self._head = None  # what the header and the histogram last showed
        self._hist = None

    def compose(self) -> ComposeResult:
        yield Static("", id="txhead", markup=False)
        yield TransactionList(self.store, id="txlist")
        yield Static("", id="histogram")

    def on_mount(self) -> None:
        self.list = self.query_one(TransactionList)
        self.refresh_view()

    @property
    def selected_row(self) -> int | None:
        """The selected transaction's first frame (its request, or the response of an orphan)."""
        tx = self.list.selected_tx
        return None if tx is None else self.store.transactions.first_row(tx)

    def refresh_view(self) -> None:
        """Take in what the store got since the last call (frames, a filter); redraw only what changed."""
        txs, lst = self.store.transactions, self.list
        keep = lst.selected_tx if txs.view_of is not self.store.view else None  # a new filter: keep the selection
        if txs.sync(self.store.view):
            lst.refresh_rows()
            if keep is not None and not lst.follow and len(txs.view):
                lst.cursor = txs.nearest_pos(keep)
        flt = self.store.filter
        what = (f"{len(txs.view)} of {len(txs)} transactions; filter {flt.describe()}: a transaction shows when "
                "its request or its response passes it" if flt.active else f"{len(txs)} transactions")
        tb = self.store.time
        head = (header(tb.title(), lst.columns()) + "\n" + what + ("  (paused)" if self.store.paused else "")
                + f"   {tb.describe()}")
        if head != self._head:
            if self._head is not None and self._head.split("\n")[0] != head.split("\n")[0]:
                lst.refresh()  # another time base: the lines' times change
            self._head = head
            self.query_one("#txhead", Static).update(head)
        self.refresh_histogram()

    def refresh_histogram(self) -> None:
        txs = self.store.transactions
        tx = self.list.selected_tx
        # following the tail, the selection changes every tick: all units then, not a unit jumping about
        whole = tx is None or self.list.all_units or self.list.follow
        unit = None if whole else unit_key(self.store.frame(txs.first_row(tx)))
        units = self.store.units
        fig = units.total() if unit is None else units.get(unit)
        if fig is None:  # a transaction of no unit's (cannot be: every request and response names one)
            fig = units.total()
            unit = None
        rows = BAR_ROWS if self.app.size.height >= 36 else 2  # 80x24: the list keeps 10 lines
        key = (unit, rows, fig.latency.n, fig.timeouts, fig.late, fig.unanswered_at_end, fig.unmeasured)
        if key == self._hist:
            return
        self._hist = key
        model = fig.model if unit is not None else None
        title = "latency, all units" if unit is None else f"latency, unit {unit}" + (f" ({model})" if model else "")
        hist = self.query_one("#histogram", Static)
        hist.styles.height = rows + 5  # its border, the figures (2), the bars, the bins (2)
        hist.update(histogram_text(fig, title, rows))

    def on_resize(self, event) -> None:
        self.refresh_view()  # the columns fit the width, the histogram the height

    def on_transaction_list_highlighted(self, message: TransactionList.Highlighted) -> None:
        self.refresh_histogram()
