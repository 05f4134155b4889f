"""The Textual App: a thin viewer over a FrameStore fed by a TuiSink.

The pipeline runs elsewhere (a worker thread given as `feed`); the App polls
the sink on a timer, takes frames into the store for a time budget (more in
between while they wait: sink.py) and redraws once per tick.
"""

from __future__ import annotations

import asyncio
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import ClassVar

from textual import on
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Input, Static, TabbedContent, TabPane

from sniffer.tui.byteview import BytesPane, ByteView, link_char_ns
from sniffer.filterlang import register_ids
from sniffer.analysis.linehealth import is_line_warning
from sniffer.tui.detail import DetailPane
from sniffer.tui.filters import filter_expr, parse_filter
from sniffer.tui.footer import KeyBar
from sniffer.tui.framelist import FrameList
from sniffer.tui.goto import parse_goto, resolve
from sniffer.tui.hangup import TerminalWatch
from sniffer.tui.linenotice import LineNotice
from sniffer.tui.gotobar import GotoBar
from sniffer.tui.store import FrameStore
from sniffer.tui.plot import JumpToFrame, PlotPane
from sniffer.tui.plotmodel import PlotSet
from sniffer.tui.readring import ReadRing
from sniffer.tui.registers import RegisterWatch
from sniffer.tui.sink import INTAKE_BUDGET_S, INTAKE_GAP_S, INTAKE_TURN_S, TuiSink
from sniffer.tui.status import status_text
from sniffer.tui.txlist import TransactionList, TransactionsPane
from sniffer.tui.units import UnitsTable
from sniffer.tui.verdicts import VerdictsPane

HELP = """\
[b]rs485-sniffer TUI[/b] — keys

  [b]1 2 3 4[/b]      frames / units / registers / transactions (below);  [b]6[/b] bytes: the reads as the
               port delivered them (time, gap in ms and characters, │ where a frame begins; ← → frame,
               Enter goes to it)
  [b]↑ ↓ PgUp PgDn[/b] move; [b]Home[/b] first; [b]End[/b] / [b]G[/b] follow the tail
  [b]Enter[/b]        focus the detail tree (select a node: its bytes light up in the hex dump)
  [b]p[/b]            jump to the paired request / response
  [b]n[/b] / [b]N[/b]        next / previous problem (error, exception, timeout, drive fault, noise)
  [b]e[/b]            errors only (toggle)
  [b]u[/b] / [b]f[/b]        only this frame's unit / function (toggle)
  [b]/[/b]            filter bar; Enter applies (a bad filter says where, and the old one stays):
               words find names, texts, registers (holding[300] 2520H 12-00), codes, hex;
               u:1,2 fc:3 role:rsp reg:2520H..2525H model:a510 t:10s..20s "Output frequency">50
               lat>20ms  err crc exc timeout fault noise warn  not and or ( )  (docs/filters.md)
  [b]c[/b]            clear all filters
  [b]space[/b]        pause the view (capture goes on); again to resume
  [b]t[/b]            times since the start → wall clock → from the time reference (the header says which;
               plots and change logs follow)
  [b]T[/b]            this frame is the time reference (*REF*); T on it again clears it
  [b]g[/b]            go to frame 1234 (or #1234), or to the first frame at or after a time: 12.5s, 350ms
               (from the reference when times are shown from it), 19:22:01.250 (wall clock)
  [b]m[/b]            bookmark; [b]][/b] / [b]\\[[/b] next / previous bookmark
  [b]x[/b]            export the filtered view or the bookmarks (MCAP, pcap, CSV) to a file
  [b]y[/b]            copy the selected frame's bytes as hex to the clipboard (OSC 52)
  [b]4[/b]            transactions: a request and its answer a line, the latency histogram below (all
               units while following the tail, else the selected transaction's unit); the frame
               filter applies (a transaction shows if its request or its response passes)
    in it:     [b]Enter[/b] / a click on the selected line: its request in Frames; [b]h[/b] histogram
               of all units / this unit; [b]n[/b] / [b]N[/b] next / previous problem; [b]u[/b] / [b]f[/b] its unit / fc
  [b]7[/b]            verdicts: what is wrong on the line, why, what to do (`sniffer diagnose` on the frames so
               far, updated as they come); Enter goes to a finding's first frame
  [b]5[/b]            plot; in Registers [b]a[/b] adds / removes the register, [b]Enter[/b] opens its change log
               (there [b]Enter[/b] goes to the change's frame, [b]Esc[/b] back)
  Plot:        [b]+ -[/b] zoom  [b]← →[/b] pan  [b]0[/b] all, follow  [b], .[/b] cursor  [b]Enter[/b] / click: go to the
               nearest sample's frame  [b]↑ ↓[/b] choose  [b]d[/b] remove  (mouse wheel: zoom)
  [b]?[/b]            this help;  [b]q[/b] / [b]Ctrl-C[/b] quit: a live capture asks first (y or Ctrl-C again stops
               it and closes its file); a replay or a viewer of `sniffer attach` just closes (the capture goes on)

Colours: [bold bright_red]!! errors / bad CRC[/], [bold magenta]E exceptions[/], [bold dark_orange]F drive faults &
alarms[/] (OL1 — Motor overload), [yellow]T timeouts & warnings[/], [grey50 italic]noise[/].
The selected frame's pair has a grey background; ←/→ #n names it.
"""


class HelpScreen(ModalScreen):
    BINDINGS: ClassVar[list[Binding]] = [Binding("escape,q,question_mark", "dismiss", "Close")]
    # at most the screen (80x24 too): what does not fit scrolls (arrows, PgUp / PgDn)
    DEFAULT_CSS = "HelpScreen { align: center middle; } HelpScreen > VerticalScroll { width: 100; max-width: 100%; " \
                  "height: auto; max-height: 100%; border: thick $primary; background: $surface; padding: 1 2; }"

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Static(HELP)


class ConfirmQuit(ModalScreen[bool]):
    """Quitting stops a live capture: y / Enter stops it, n / Esc goes back (keys typed by mistake,
    a `q` meant for the filter bar, end nothing)."""

    BINDINGS: ClassVar[list[Binding]] = [Binding("y,enter", "answer(True)", "Stop"),
                                         Binding("n,escape,q", "answer(False)", "Go on")]
    DEFAULT_CSS = "ConfirmQuit { align: center middle; } ConfirmQuit > Static { width: 64; height: auto; " \
                  "border: thick $error; background: $surface; padding: 1 2; }"

    def __init__(self, what: str) -> None:
        super().__init__()
        self.what = what

    def compose(self) -> ComposeResult:
        yield Static(f"Stop the live capture{self.what}?\n\n"
                     "[b]y[/b] / Ctrl-C stop it and quit    [b]n[/b] / Esc go on capturing")

    def action_answer(self, stop: bool) -> None:
        self.dismiss(stop)


async def _loop_idle(loop, most: int = 64) -> None:
    """Give the event loop INTAKE_GAP_S, then as long as it has callbacks ready (a key's way to its widget
    is several hops, each a callback: one turn between two hops made a key wait several turns), at most
    `most` rounds.  `_ready` is CPython's event loop's queue of ready callbacks (private: a loop without it
    just gets the gap)."""
    await asyncio.sleep(INTAKE_GAP_S)
    for _ in range(most):
        if not getattr(loop, "_ready", None):
            return
        await asyncio.sleep(0)


def _terminal_fd(driver_class) -> int | None:
    """The terminal a Linux terminal driver reads keys from; None for any other driver (tests, the web)."""
    try:
        from textual.drivers.linux_driver import LinuxDriver
    except ImportError:
        return None
    if not (isinstance(driver_class, type) and issubclass(driver_class, LinuxDriver)) or sys.__stdin__ is None:
        return None
    return sys.__stdin__.fileno()


class SnifferApp(App):
    TITLE = "rs485-sniffer"
    CSS = """
    #filterbar { dock: top; display: none; }
    #filterbar.shown { display: block; }
    #status { height: 1; background: $panel; padding: 0 1; }
    TabbedContent { height: 1fr; }
    #framespane { height: 1fr; }
    FrameList { height: 3fr; }
    DetailPane { height: 2fr; }
    """
    BINDINGS: ClassVar[list[Binding]] = [
        Binding("1", "tab('frames')", "Frames"),
        Binding("2", "tab('units')", "Units"),
        Binding("3", "tab('registers')", "Registers"),
        Binding("4", "tab('transactions')", "Transactions", show=False),
        Binding("5", "tab('plot')", "Plot", show=False),
        Binding("7", "tab('verdicts')", "Verdicts", show=False),
        Binding("p", "pair", "Pair"),
        Binding("n", "problem(1)", "Next err"),
        Binding("N", "problem(0)", "Prev err", show=False),
        Binding("e", "errors_only", "Errors"),
        Binding("u", "unit_filter", "Unit"),
        Binding("f", "function_filter", "Func", show=False),
        # priority: handled as the App takes the key from the driver, before the keys typed after it are
        # passed on, so those reach the filter bar (not the frame list's commands: 'q' would quit)
        Binding("slash", "filter_bar", "Filter", priority=True),
        Binding("c", "clear_filters", "Clear", show=False),
        Binding("space", "pause", "Pause"),
        Binding("m", "bookmark", "Mark"),
        Binding("right_square_bracket", "bookmark_jump(1)", "Next mark", show=False),
        Binding("left_square_bracket", "bookmark_jump(0)", "Prev mark", show=False),
        Binding("enter", "focus_detail", "Detail", show=False),
        Binding("question_mark,f1", "help", "Help"),
        Binding("q", "quit", "Quit"),
        # Ctrl-C stops, as on the command line (not Textual's "press ctrl+q" notice): priority, so a focused
        # bar's copy does not take it
        Binding("ctrl+c", "interrupt", "Stop", show=False, priority=True),
        # export / copy / raw bytes
        Binding("x", "export", "Export"),
        Binding("y", "copy_hex", "Copy hex", show=False),
        Binding("6", "bytes_tab", "Bytes"),
        # time: the base the list shows, a time reference, go to a frame or a time (priority: see slash)
        Binding("t", "time_base", "Time"),
        Binding("T", "time_reference", "Time ref", show=False),
        Binding("g", "goto_bar", "Go to", priority=True),
    ]

    def __init__(self, sink: TuiSink, feed: Callable[[TuiSink, threading.Event], object] | None = None, *,
                 source_label: str = "", capture_path: str | None = None, source_path: str | None = None,
                 registry=None, poll_hz: float = 15.0, max_batch: int = 5_000,
                 clock: Callable[[], float] = time.monotonic, live: bool = False) -> None:
        super().__init__()
        self.live = live  # quitting stops a capture running here: ask first
        self.give_way = None  # a GiveWay (processes/cpu_yield.py) while it views a capture running on this machine
        self._terminal = TerminalWatch(None)  # on_mount: the terminal it reads keys from (hangup.py)
        self.sink = sink
        self.feed = feed
        self.stop_event = threading.Event()  # the feed's stop (a session's: it is set when the feed ends too)
        self.quitting = threading.Event()  # the App is closing: what runs on its workers (an export) stops
        self.source_label = source_label
        self.capture_path = capture_path
        self.source_path = source_path  # the capture a replay views (a file, a folder): exports go beside it
        self.registry = registry  # read only, for the units table's given / guessed models
        self.poll_hz = poll_hz
        self.max_batch = max_batch
        self.store = FrameStore(ids=register_ids(registry))  # its register watch applies the frames' `writes`
        self.feed_error: BaseException | None = None
        self.feed_result = None
        self._thread: threading.Thread | None = None
        self.clock = clock  # a fixed clock makes the status bar deterministic (snapshots)
        self.t_start = clock()
        self._rate = (self.t_start, 0, 0)  # (when, frames, bytes) at the last rate sample
        self.frames_per_s = 0.0
        self.bytes_per_s = 0.0
        self._ticks = 0
        self._tables_at = None  # (store state, tab) the units / registers tables were last built for
        self._status_text = None
        self._shown_rows = 0  # store rows when the list was last told
        self._intake_task: asyncio.Task | None = None  # taking a backlog in between polls (_intake)
        self.notices: deque[str] = deque()  # lines a capture process said on stderr: shown as notifications
        self.export_status: str | None = None  # an export running on its worker: how far it is
        self.reads = ReadRing()  # the byte view's last reads (sniffer.analysis.reads)
        self.line_notice = LineNotice(source_path)  # most frames bad: the line settings are probably wrong

    # ---------------------------------------------------------------- layout
    def compose(self) -> ComposeResult:
        yield Input(placeholder='filter: words  u:1,2  fc:3  reg:2520H  "Output frequency" > 50  lat>20ms  t:10s..20s  '
                                'err  not/and/or (...)   (Enter applies, Esc closes)', id="filterbar")
        yield GotoBar(id="gotobar")
        with TabbedContent(initial="frames"):
            with TabPane("Frames", id="frames"), Vertical(id="framespane"):
                yield FrameList(self.store, id="list")
                yield DetailPane(id="detail")
            with TabPane("Units", id="units"):
                yield UnitsTable(self.store, self.registry, id="unitstable")
            plots = PlotSet()  # the registers on the plot: added in the Registers tab, drawn in the Plot tab
            with TabPane("Registers", id="registers"):
                yield RegisterWatch(self.store, plots, id="regwatch")
            with TabPane("Transactions", id="transactions"):
                yield TransactionsPane(self.store, id="txpane")
            with TabPane("Plot", id="plot"):
                yield PlotPane(self.store, plots, id="plotpane")
            with TabPane("Bytes", id="bytes"):
                yield BytesPane(self.reads, self.store, id="bytespane")
            with TabPane("Verdicts", id="verdicts"):
                yield VerdictsPane(id="verdictspane")
        yield Static("", id="status")
        yield KeyBar()

    def on_mount(self) -> None:
        self._terminal = TerminalWatch(_terminal_fd(self.driver_class))
        if self.give_way is not None:
            self.give_way.watch_loop(asyncio.get_running_loop())
        # widgets of the main screen, kept: App.query_one looks at whichever screen is on top (help)
        self.frame_list = self.query_one("#list", FrameList)
        self.detail = self.query_one("#detail", DetailPane)
        self.status = self.query_one("#status", Static)
        self.tabs = self.query_one(TabbedContent)
        self.filter_bar = self.query_one("#filterbar", Input)
        self.tx_pane = self.query_one("#txpane", TransactionsPane)
        self.byte_view = self.query_one("#byteview", ByteView)
        self.frame_list.focus()
        self.set_interval(1 / self.poll_hz, self._tick)
        if self.feed is not None:
            self._thread = threading.Thread(target=self._run_feed, name="tui-feed", daemon=True)
            self._thread.start()

    def on_unmount(self) -> None:
        if self._intake_task is not None:
            self._intake_task.cancel()

    def _run_feed(self) -> None:
        try:
            self.feed_result = self.feed(self.sink, self.stop_event)
        except BaseException as e:  # noqa: BLE001 - shown in the status bar
            self.feed_error = e
            self.sink.error = f"{type(e).__name__}: {e}"
        finally:
            self.sink.closed.set()

    def stop_feed(self, timeout: float = 5.0) -> None:
        self.quitting.set()
        self.stop_event.set()
        self.sink.release()  # a replay waiting for the UI to drain would not see the stop
        if self._thread is not None:
            self._thread.join(timeout)

    async def action_interrupt(self) -> None:
        """Ctrl-C: quit as `q` does (a live capture asks first); Ctrl-C again while it asks stops it."""
        if isinstance(self.screen, ConfirmQuit):
            self.screen.dismiss(True)
            return
        await self.action_quit()

    async def action_quit(self) -> None:
        if self.live and not self.caught_up:  # a live capture is still running in this process
            what = f" into {self.capture_path}" if self.capture_path else ""

            def answered(stop: bool | None) -> None:
                if stop:
                    self.stop_feed()
                    self.exit(self.feed_result)

            self.push_screen(ConfirmQuit(what), answered)
            return
        self.stop_feed()
        self.exit(self.feed_result)

    # ---------------------------------------------------------------- polling
    @property
    def caught_up(self) -> bool:
        """The feed has finished and every frame it produced is in the store."""
        return self.sink.closed.is_set() and self.sink.backlog == 0

    def _tick(self) -> None:
        """The poll timer: frames in for at most INTAKE_BUDGET_S (a key waits no longer), then the view."""
        if self._terminal.gone():  # hangup.py: quit as on SIGHUP (a live capture stopped, its MCAP kept)
            self.stop_feed()
            self.exit(self.feed_result)
            return
        self.poll(INTAKE_BUDGET_S)
        if self.sink.backlog and (self._intake_task is None or self._intake_task.done()):
            self._intake_task = asyncio.create_task(self._intake())

    async def _intake(self) -> None:
        """Between two polls, while frames wait: turns of INTAKE_TURN_S taking them into the store, each
        followed by INTAKE_GAP_S of the event loop's own work (a key, a timer, a redraw), so a replay loads
        at most of the UI thread's time and a key waits about one turn (the next poll shows the frames)."""
        loop = asyncio.get_running_loop()
        while self.sink.drain_into(self._take, budget_s=INTAKE_TURN_S) and self.sink.backlog:
            await _loop_idle(loop)

    def poll(self, budget_s: float | None = None) -> None:
        """Frames into the store (at most max_batch, and for at most `budget_s` if given), then the view."""
        while self.notices:
            line = self.notices.popleft()
            if is_line_warning(line):
                continue  # the capture's own warning: the App says it from the frames it shows (_take)
            bad = "error" in line or "warning" in line or "lost" in line
            self.notify(line.removeprefix("sniffer: "), title="capture", severity="warning" if bad else "information",
                        timeout=8 if bad else 4)
        if self.sink.info is not None and not len(self.store):
            self.store.t0_ns = self.sink.info.t0_ns
            self.store.time.wall_anchor_ns = self.sink.info.wall_anchor_ns
            self.store.start_diagnosis(self.sink.info, self.registry)
        self.sink.drain_into(self._take, limit=self.max_batch, budget_s=budget_s)
        before = self._shown_rows  # frames _intake added count too
        if len(self.store) != before and (budget_s is None or self.frame_list.tail_due(len(self.store) - before)):
            self._shown_rows = len(self.store)
            self.frame_list.refresh_rows(grown=True)
            if self.tabs.active == "transactions":
                self.tx_pane.refresh_view()
        reads = self.sink.drain_reads()
        if reads:
            self.reads.add(reads)
            self._bytes_shown()
        self._ticks += 1
        now = self.clock()
        when, n0, b0 = self._rate
        if now - when >= 1.0:
            self.frames_per_s = (len(self.store) - n0) / (now - when)
            self.bytes_per_s = (self.sink.bytes_in - b0) / (now - when)
            self._rate = (now, len(self.store), self.sink.bytes_in)
        # idle means idle: tables only when the store changed, the status bar only when its text did
        shown = (self.store.generation, len(self.store), self.store.book.version, self.tabs.active)
        if (self._ticks % max(int(self.poll_hz / 2), 1) == 0 and shown != self._tables_at
                or not before and self._shown_rows):
            self._tables_at = shown
            self.refresh_tables()
        text = status_text(self)
        if text != self._status_text:
            self._status_text = text
            self.status.update(text, layout=False)  # one line, always: its text changing moves nothing else

    def _take(self, frames: list) -> None:
        """Frames into the store, and judged: a line whose frames are mostly bad is said once (linenotice.py)."""
        self.store.add(frames)
        for text in self.line_notice.take(frames, self.sink.info):
            self.notify(text, title="line settings?", severity="warning", timeout=30, markup=False)

    def refresh_tables(self) -> None:
        active = self.tabs.active
        if active == "units":
            self.tabs.query_one("#unitstable", UnitsTable).update_rows()
        elif active == "registers":
            self.tabs.query_one("#regwatch", RegisterWatch).update_rows()
        elif active == "transactions":
            self.tx_pane.refresh_view()
        elif active == "plot":
            self.tabs.query_one("#plotpane", PlotPane).update_plot()
        elif active == "verdicts":
            self.tabs.query_one("#verdictspane", VerdictsPane).update_findings(self.store.diagnosis.findings())

    def capture_size(self) -> int | None:
        path = self.capture_path or self.sink.capture_path
        if not path:
            return None
        from sniffer.formats.outputs import readable

        try:
            return os.path.getsize(readable(path)[0])  # its part file while the capture writes it
        except OSError:
            return None

    # ---------------------------------------------------------------- selection
    def on_frame_list_selected(self, message: FrameList.Selected) -> None:
        self.show_detail(message.row, following=message.following)

    def show_detail(self, row: int | None, *, following: bool = False) -> None:
        """The detail of a row, its time in the list's base and its Δt to the previous shown frame
        (`following`: the tail's newest frame, shown at a readable pace: DetailPane.show)."""
        store = self.store
        pos = None if row is None else store.pos_of_row(row)
        prev = store.view[pos - 1] if pos else None
        self.detail.show(None if row is None else store.frame(row), store.time,
                         None if prev is None else (store.t_ns[prev], store.frame(prev).index), following=following)

    @property
    def selected_frame(self):
        row = self.frame_list.selected_row
        if self.tabs.active == "transactions":  # u / f act on the selected transaction
            row = self.tx_pane.selected_row
        return None if row is None else self.store.frame(row)

    def on_transaction_list_chosen(self, message: TransactionList.Chosen) -> None:
        """Open a transaction's request in the Frames tab (its response if the filter hides the request)."""
        req, rsp = self.store.transactions.rows(message.tx)
        row = req if req >= 0 and self.store.pos_of_row(req) is not None else rsp
        self.action_tab("frames")
        self._goto(row if row >= 0 else None, "frame of this transaction in view")

    def _goto(self, row: int | None, what: str) -> bool:
        if row is None or not self.frame_list.select_row(row):
            self.notify(f"no {what}", timeout=2)
            return False
        return True

    def action_tab(self, tab: str) -> None:
        self.tabs.active = tab
        self.refresh_tables()
        if tab == "frames":
            self.frame_list.focus()
        elif tab == "transactions":
            self.tx_pane.list.focus()
        elif tab == "plot":  # the plot takes the keys (zoom, pan, cursor)
            self.query_one("#plotview").focus()
        elif tab == "verdicts":
            self.query_one("#verdict-list").focus()
        else:  # the tab's table takes the keys (arrows move in it at once)
            from textual.widgets import DataTable

            pane = self.query_one("#unitstable" if tab == "units" else "#regwatch")
            table = pane if isinstance(pane, DataTable) else pane.query_one(DataTable)
            table.focus()

    def on_jump_to_frame(self, message: JumpToFrame) -> None:
        """A change in the change log or a sample on the plot: its frame in the Frames tab."""
        self.go_to_frame(message.index)

    def action_pair(self) -> None:
        row = self.frame_list.selected_row
        if row is not None:
            self._goto(self.store.pair_row(row), "paired frame (filtered out or none)")

    def action_problem(self, forward: int) -> None:
        row = self.frame_list.selected_row
        start = row if row is not None else -1
        self._goto(self.store.next_problem(start, bool(forward)), "further problem")

    def action_bookmark(self) -> None:
        row = self.frame_list.selected_row
        if row is not None:
            self.store.toggle_bookmark(row)
            self.frame_list.refresh()

    def action_bookmark_jump(self, forward: int) -> None:
        row = self.frame_list.selected_row
        self._goto(self.store.next_bookmark(row if row is not None else -1, bool(forward)), "bookmark")

    def action_pause(self) -> None:
        paused = self.store.pause()
        if not paused:
            self.frame_list.follow = True
        self._after_view_change()

    def action_focus_detail(self) -> None:
        if self.focused is self.frame_list:
            self.detail.query_one("Tree").focus()

    # ---------------------------------------------------------------- filters
    def _after_view_change(self, keep: int | None = None) -> None:
        fl = self.frame_list
        keep = fl.selected_row if keep is None else keep
        fl.refresh_rows()
        if keep is not None and len(self.store.view) and not fl.follow:
            fl.cursor = self.store.nearest_pos(keep)
        if self.tabs.active == "transactions":
            self.tx_pane.refresh_view()
        self.status.update(status_text(self))

    def apply_filter(self, **kw) -> None:
        keep = self.frame_list.selected_row
        self.frame_list.follow = False
        self.store.update_filter(**kw)
        self._after_view_change(keep)

    def action_errors_only(self) -> None:
        self.apply_filter(errors_only=not self.store.filter.errors_only)

    def action_unit_filter(self) -> None:
        f = self.selected_frame
        if self.store.filter.units is not None:
            self.apply_filter(units=None, links=None)
        elif f is not None and f.unit is not None:  # with several links: that unit of that link
            self.apply_filter(units=frozenset({f.unit}), links=frozenset({f.link.lower()}) if f.link else None)

    def action_function_filter(self) -> None:
        f = self.selected_frame
        if self.store.filter.functions is not None:
            self.apply_filter(functions=None)
        elif f is not None and f.function is not None:
            self.apply_filter(functions=frozenset({f.function & 0x7F}))

    def action_clear_filters(self) -> None:
        self.apply_filter(units=None, links=None, functions=None, roles=None, errors_only=False, text="")

    def action_filter_bar(self) -> None:
        bar = self.filter_bar
        if isinstance(self.focused, Input):  # a '/' typed in the filter (or another bar) itself
            self.focused.insert_text_at_cursor("/")
            return
        if self.screen is not self.screen_stack[0]:  # help or a question on top: not now
            return
        bar.value = filter_expr(self.store.filter)
        bar.add_class("shown")
        # focus now, not after the queued keys (Widget.focus waits for the message queue): what is
        # typed right after '/' is filter text, never commands ('q' would quit)
        bar.screen.set_focus(bar)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "filterbar":
            try:
                kw = parse_filter(event.value)
            except ValueError as e:
                self.notify(str(e), severity="error")
                return
            event.input.remove_class("shown")
            self.frame_list.screen.set_focus(self.frame_list)
            self.apply_filter(**kw)

    def on_key(self, event) -> None:
        bar = self.filter_bar
        if event.key == "escape" and bar.has_class("shown"):
            bar.remove_class("shown")
            self.frame_list.screen.set_focus(self.frame_list)
            event.stop()
        elif event.key == "escape" and self.focused is not None and self.detail in self.focused.ancestors_with_self:
            self.frame_list.focus()  # Esc leaves the detail tree for the frame list
            event.stop()

    def action_help(self) -> None:
        self.push_screen(HelpScreen())

    # ---------------------------------------------------------------- export, copy
    def action_export(self) -> None:
        from sniffer.tui.exportscreen import ExportScreen, start_export

        if self.screen is not self.screen_stack[0]:  # help or a question on top: not now
            return
        if self.export_status is not None:
            self.notify("an export is running (its progress is in the status bar)", timeout=3)
            return
        path = self.capture_path or self.sink.capture_path or self.source_path
        screen = ExportScreen(path, len(self.store.view), len(self.store.bookmarks), inputs=[path])
        self.push_screen(screen, lambda job: job and start_export(self, job))

    def action_copy_hex(self) -> None:
        f = self.selected_frame
        if self.tabs.active == "bytes":  # the byte view's frame
            row = None if self.byte_view.frame is None else self.store.row_of.get(self.byte_view.frame)
            f = None if row is None else self.store.frame(row)
        if f is None:
            self.notify("no frame selected", timeout=2)
            return
        self.copy_to_clipboard(f.raw.hex())
        self.notify(f"copied frame #{f.index}: {len(f.raw)} bytes, {f.raw[:24].hex(' ')}"
                    + (" …" if len(f.raw) > 24 else ""), timeout=3, markup=False)

    # ---------------------------------------------------------------- the byte view
    def action_bytes_tab(self) -> None:
        self.tabs.active = "bytes"
        self.byte_view.focus()

    @on(TabbedContent.TabActivated, pane="#bytes")
    def _bytes_tab_activated(self) -> None:
        self._bytes_follow_list()
        self._bytes_shown()

    def _bytes_follow_list(self) -> None:
        """Opened, the byte view shows the frame selected in the list (the newest read while the list follows)."""
        f = self.selected_frame
        self.byte_view.follow = self.frame_list.follow or f is None
        if not self.byte_view.follow:
            self.byte_view.show_frame(f.index)

    def _bytes_shown(self) -> None:
        if self.tabs.active == "bytes":
            self.byte_view.char_ns = link_char_ns(self.sink.info)
            self.byte_view.refresh_reads()

    def on_byte_view_chosen(self, message: ByteView.Chosen) -> None:
        self.go_to_frame(message.index)

    def go_to_frame(self, index: int) -> None:
        """Frame #index selected in the Frames tab (the byte view's Enter, a change, a plotted sample)."""
        row = self.store.row_of.get(index)
        if row is None:
            self.notify(f"frame #{index} is not in this view (older than what it was sent)", timeout=3)
        elif self.store.pos_of_row(row) is None:
            self.notify(f"frame #{index} is not in the list: filtered out (c clears the filters) or after the "
                        "pause (space resumes)", timeout=3)
        else:
            self.tabs.active = "frames"
            self.frame_list.select_row(row)
            self.frame_list.focus()
    # ---------------------------------------------------------------- time and go to
    def _after_time_change(self) -> None:
        self.frame_list.refresh_rows()  # the columns fit the new times, the header names the base
        self.show_detail(self.frame_list.selected_row)
        self.tx_pane.refresh_view()
        self.tabs.query_one("#changelog").refresh()  # the registers' times and the plots' time axes follow too
        self.refresh_tables()

    def action_time_base(self) -> None:
        if self.store.time.cycle() is None:
            self.notify("Times are since the start only: this capture has no wall-clock start and no time "
                        "reference is set (T sets one)", timeout=4)
            return
        self._after_time_change()

    def action_time_reference(self) -> None:
        row = self.frame_list.selected_row
        if row is not None:
            f = self.store.frame(row)
            self.store.time.toggle_reference(row, f.t_ns, f.index)
            self._after_time_change()

    def action_goto_bar(self) -> None:
        if isinstance(self.focused, Input):  # a 'g' typed in a bar is text
            self.focused.insert_text_at_cursor("g")
        elif self.screen is self.screen_stack[0]:  # not under the help or a question
            self.query_one("#gotobar", GotoBar).open()

    @on(Input.Submitted, "#gotobar")
    def goto(self, event: Input.Submitted) -> None:
        """Go where the bar says; bad input: one error line, the bar stays open to fix it."""
        bar = self.query_one("#gotobar", GotoBar)
        if event.value.strip():
            try:
                row, note = resolve(self.store, parse_goto(event.value, self.store.time, self.store.last_t_ns))
            except ValueError as e:
                self.notify(str(e), severity="error", timeout=5)
                return
            self.tabs.active = "frames"
            self.frame_list.select_row(row)
            if note:
                self.notify(note, severity="warning", timeout=5)
        bar.action_close()
