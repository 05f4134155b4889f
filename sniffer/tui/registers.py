"""Register watch: the register shadow per unit (latest value of every register), changes
highlighted, a sparkline of the selected register.  The model is shadow.RegisterBook."""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import DataTable, Sparkline, Static

from .model import FrameStore

# "unit" is the Modbus unit (as in the frame list); "eng" the value's engineering unit (Hz, A, V)
COLUMNS = ("unit", "table", "addr", "name", "value", "eng", "raw", "changes", "updated")
_VALUE = COLUMNS.index("value")
CHANGED_NS = 2_000_000_000  # a change shows highlighted for 2 s of capture time


class RegisterWatch(Vertical):
    DEFAULT_CSS = """
    RegisterWatch > DataTable { height: 1fr; }
    RegisterWatch > #spark-label { height: 1; padding: 0 1; }
    RegisterWatch > Sparkline { height: 4; }
    """

    def __init__(self, store: FrameStore, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self.chosen: tuple[int, str, int] | None = None
        self._shown: dict[str, tuple] = {}  # row key -> cells on screen
        self._dropped = 0  # the book's count of dropped rows when the table last removed them

    def compose(self) -> ComposeResult:
        yield DataTable(cursor_type="row", zebra_stripes=True, id="regs")
        yield Static("select a numeric register for its plot", id="spark-label")
        yield Sparkline([], id="spark")

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
        for rv in rows:
            key = f"{rv.unit}:{rv.table}:{rv.address}"
            fresh = bool(rv.changes) and now - rv.changed_ns < CHANGED_NS
            name = rv.name if not rv.id or rv.id in rv.name else f"{rv.id} {rv.name}"
            cells = (str(rv.unit), rv.table, address_text(rv), name[:36],
                     (str(rv.value) if not rv.text else f"{rv.value} {rv.text}")[:40], rv.eng_unit or "",
                     str(rv.raw), str(rv.changes), f"{(rv.t_ns - store.t0_ns) / 1e9:.3f}s", fresh)
            old = shown.get(key)
            if old == cells:
                continue
            shown[key] = cells
            row = list(cells[:-1])
            row[_VALUE] = Text(cells[_VALUE], "bold black on yellow" if fresh else "")
            if old is None:
                t.add_row(*row, key=key)
                continue
            for i, col in enumerate(COLUMNS):
                if i == _VALUE or cells[i] != old[i]:
                    t.update_cell(key, col, row[i])
        self._spark()

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is None or event.row_key.value is None:
            return
        u, table, a = event.row_key.value.split(":")
        self.chosen = (int(u), table, int(a))
        self._spark()

    def _spark(self) -> None:
        rv = self.store.registers.get(self.chosen) if self.chosen else None
        labels, sparks = self.query("#spark-label"), self.query("#spark")
        if not labels or not sparks:  # not mounted yet
            return
        label, spark = labels.first(Static), sparks.first(Sparkline)
        if rv is None or not rv.history:
            spark.data = []
            label.update("select a numeric register for its plot" if rv is None else f"{rv.name}: not numeric")
            return
        h = list(rv.history)
        label.update(f"unit {rv.unit} {rv.table} {address_text(rv)} {rv.name}: min {min(h):g} max {max(h):g} "
                     f"last {h[-1]:g} {rv.eng_unit or ''} ({len(h)} samples)")
        spark.data = h


def address_text(rv) -> str:
    """A row's address as the manuals write it: "2520H", or "2510H..2511H" for a value of several
    registers (the parameter id, where the map has one, leads the name)."""
    return f"{rv.address:04X}H" if rv.words == 1 else f"{rv.address:04X}H..{rv.address + rv.words - 1:04X}H"
