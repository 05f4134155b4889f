"""Register watch: the latest value of every decoded register, changes highlighted, a sparkline."""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import DataTable, Sparkline, Static

from .model import FrameStore

COLUMNS = ("unit", "table", "addr", "name", "value", "unit ", "changes", "updated")
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
        self.chosen: tuple[int, int] | None = None

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
        t = self.query_one("#regs", DataTable)
        store = self.store
        now = max((f.t_ns for f in store.frames[-1:]), default=0)
        for rv in store.register_rows():
            key = f"{rv.unit}:{rv.table}:{rv.address}"
            fresh = rv.changes and now - rv.changed_ns < CHANGED_NS
            value = Text(str(rv.value) if not rv.text else f"{rv.value} {rv.text}"[:60],
                         "bold black on yellow" if fresh else "")
            cells = (str(rv.unit), rv.table, str(rv.address), rv.name[:40], value, rv.eng_unit or "", str(rv.changes),
                     f"{(rv.t_ns - store.t0_ns) / 1e9:.3f}s")
            if key in t.rows:
                for col, val in zip(COLUMNS[4:], cells[4:]):
                    t.update_cell(key, col, val)
            else:
                t.add_row(*cells, key=key)
        self._spark()

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is None or event.row_key.value is None:
            return
        u, table, a = event.row_key.value.split(":")
        self.chosen = (int(u), table, int(a))
        self._spark()

    def _spark(self) -> None:
        rv = self.store.registers.get(self.chosen) if self.chosen else None
        label = self.query_one("#spark-label", Static)
        spark = self.query_one("#spark", Sparkline)
        if rv is None or not rv.history:
            spark.data = []
            label.update("select a numeric register for its plot" if rv is None else f"{rv.name}: not numeric")
            return
        h = list(rv.history)
        label.update(f"unit {rv.unit} {rv.table} {rv.address} {rv.name}: min {min(h):g} max {max(h):g} "
                     f"last {h[-1]:g} {rv.eng_unit or ''} ({len(h)} samples)")
        spark.data = h
