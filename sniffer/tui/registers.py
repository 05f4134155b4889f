"""Register watch: the register shadow per unit (latest value of every register), changes
highlighted; under it the highlighted register's change log and its plot over capture time.
`a` adds the highlighted register to the Plot tab (or removes it).  The model is shadow.RegisterBook."""

from __future__ import annotations

from typing import ClassVar

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Static

from sniffer.frame import LinkUnit
from sniffer.tui.changelog import ChangeLog
from sniffer.tui.store import FrameStore
from sniffer.tui.plot import PlotView
from sniffer.tui.plotmodel import PlotSet

# "unit" is the Modbus unit (as in the frame list); "eng" the value's engineering unit (Hz, A, V)
COLUMNS = ("unit", "table", "addr", "name", "value", "eng", "raw", "changes", "updated")
_NAME, _VALUE = COLUMNS.index("name"), COLUMNS.index("value")
CHANGED_NS = 2_000_000_000  # a change shows highlighted for 2 s of capture time
HINT = "Enter: its change log   a: add to / remove from the plot (5)"


class RegisterWatch(Vertical):
    BINDINGS: ClassVar[list[Binding]] = [
        Binding("a", "plot", "Plot it"),
        Binding("escape", "back", "Back", show=False),
    ]
    DEFAULT_CSS = """
    RegisterWatch > DataTable { height: 1fr; }
    RegisterWatch > #regbottom { height: 35%; min-height: 7; }
    RegisterWatch #logside { width: 1fr; }
    RegisterWatch #log-label { height: 1; padding: 0 1; }
    RegisterWatch #regplot { width: 1fr; }
    """

    def __init__(self, store: FrameStore, plots: PlotSet | None = None, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self.plots = plots if plots is not None else PlotSet()  # the Plot tab's registers
        self.chosen: tuple[int, str, int] | None = None
        self._shown: dict[str, tuple] = {}  # row key -> cells on screen
        self._dropped = 0  # the book's count of dropped rows when the table last removed them
        self._one = PlotSet()  # the highlighted register, for the plot beside its change log
        self._label = HINT

    def compose(self) -> ComposeResult:
        yield DataTable(cursor_type="row", zebra_stripes=True, id="regs")
        with Horizontal(id="regbottom"):
            with Vertical(id="logside"):
                yield Static(HINT, id="log-label")
                yield ChangeLog(self.store, id="changelog")
            yield PlotView(self.store, self._one, removable=False, id="regplot")

    def on_mount(self) -> None:
        t = self.query_one("#regs", DataTable)
        for c in COLUMNS:
            t.add_column(c, key=c)
        self.update_rows()

    def update_rows(self) -> None:
        found = self.query("#regs")
        if not found:  # asked before its children are mounted (a poll right after the tab opened)
            return
        t = found.first(DataTable)
        store = self.store
        now = store.last_t_ns
        shown = self._shown
        rows = store.register_rows()
        if store.book.dropped != self._dropped:  # registers joined into a value of several: their rows go
            self._dropped = store.book.dropped
            for key in set(shown) - {f"{rv.unit}:{rv.table}:{rv.address}" for rv in rows}:
                del shown[key]
                t.remove_row(key)
        colours = self.plots.colours
        for rv in rows:
            key = f"{rv.unit}:{rv.table}:{rv.address}"
            fresh = bool(rv.changes) and now - rv.changed_ns < CHANGED_NS
            cells = (str(rv.unit), rv.table, rv.address_text, rv.title[:36],
                     (str(rv.value) if not rv.text else f"{rv.value} {rv.text}")[:40], rv.eng_unit or "",
                     str(rv.raw), str(rv.changes), store.time.text(rv.t_ns), fresh,
                     colours.get((rv.unit, rv.table, rv.address)))
            old = shown.get(key)
            if old == cells:
                continue
            shown[key] = cells
            row = list(cells[:-2])
            row[_VALUE] = Text(cells[_VALUE], "bold black on yellow" if fresh else "")
            if cells[-1]:  # plotted: the name in its colour in the plot
                row[_NAME] = Text(cells[_NAME], f"bold {cells[-1]}")
            if old is None:
                t.add_row(*row, key=key)
                continue
            for i, col in enumerate(COLUMNS):
                if i in (_NAME, _VALUE) or cells[i] != old[i]:
                    t.update_cell(key, col, row[i])
        self._show_chosen()

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is None or event.row_key.value is None:
            return
        u, table, a = event.row_key.value.rsplit(":", 2)  # the unit may be a link's: "drives:1"
        link, _, n = u.rpartition(":")
        self.chosen = (LinkUnit(link, int(n)) if link else int(n), table, int(a))
        self._show_chosen()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        """Enter on a register: into its change log (Enter there goes to the frame, Esc comes back)."""
        self.query_one("#changelog", ChangeLog).focus()

    def _show_chosen(self) -> None:
        logs = self.query("#changelog")
        if not logs:  # not mounted yet
            return
        rv = self.store.registers.get(self.chosen) if self.chosen else None
        log = logs.first(ChangeLog)
        log.show(rv)
        if rv is None:
            text = HINT
        elif not rv.history.seen:
            text = f"{rv.name}: not numeric, no change log"
        else:
            s = rv.history
            text = f"{rv.address_text} {rv.name}: {s.changes} changes, {s.seen} samples" + (
                f" ({len(s)} kept)" if len(s) < s.seen else "")
        if text != self._label:
            self._label = text
            self.query_one("#log-label", Static).update(text)
        self._one.only(self.chosen if rv is not None and rv.history.seen else None)
        self.query_one("#regplot", PlotView).update_plot()

    def action_plot(self) -> None:
        rv = self.store.registers.get(self.chosen) if self.chosen else None
        if rv is None:
            return
        if self.chosen in self.plots:
            self.plots.remove(self.chosen)
            self.notify(f"{rv.name}: off the plot", timeout=2)
        elif not rv.history.seen:
            self.notify(f"{rv.name} is not numeric: nothing to plot", severity="warning", timeout=3)
        elif not self.plots.add(self.chosen):
            self.notify(f"the plot holds {self.plots.limit} registers: remove one first (d in the Plot tab)",
                        severity="warning", timeout=3)
        else:
            self.notify(f"{rv.name}: on the plot (5)", timeout=2)
        self.update_rows()

    def action_back(self) -> None:
        """Esc in the change log or the plot goes back to the register table."""
        self.query_one("#regs", DataTable).focus()

