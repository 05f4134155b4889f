"""Units table: one row per unit seen on the bus, its figures (sniffer.analysis.unitfigures: one definition each,
the same the report, the status file, `diff`, MQTT and the dataset's `units` query show)."""

from __future__ import annotations

from textual.widgets import DataTable

from sniffer.tui.store import FrameStore

# latencies in ms to the microsecond, as the frames have them; poll/s is the recent rate (the report's is the mean)
COLUMNS = ("unit", "model", "req", "rsp", "CRC err", "exc", "timeouts", "retries", "faults", "alarms", "lat min",
           "lat median", "lat p95", "lat max", "poll/s 10s", "last seen")


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def unit_cells(st, t0_ns: int, guesses: dict | None = None, given: dict | None = None) -> tuple:
    """A unit's row; `st.unit` is the number, or (link, number) in a capture of several links, whose
    given models and guesses are its link's registry's (the frames' models say them)."""
    model = st.model or "-"
    if not isinstance(st.unit, int):
        guesses = given = None
    if not st.good:  # only CRC-bad frames named it: likely a corrupted unit byte, not a device
        model = "ghost? (CRC-bad frames only)"
    elif given and st.unit in given:
        model = f"{given[st.unit]} (given)"
    elif guesses and st.unit in guesses:
        g = guesses[st.unit]
        model = f"{g[0]} (guess {g[1]:.0%})"
    lat = st.latency
    return (str(st.unit), model, str(st.requests), str(st.responses), str(st.crc_errors), str(st.exceptions),
            str(st.timeouts), str(st.retries), str(st.faults), str(st.alarms),
            _ms(lat.min), _ms(lat.median), _ms(lat.quantile(0.95)), _ms(lat.max), f"{st.poll_rate:.1f}",
            f"{(st.last_ns - t0_ns) / 1e9:.3f}s")


class UnitsTable(DataTable):
    DEFAULT_CSS = "UnitsTable { height: 1fr; }"

    def __init__(self, store: FrameStore, registry=None, **kw) -> None:
        # the unit stays on screen when a narrow terminal (80 columns) scrolls to the latencies (←/→)
        super().__init__(cursor_type="row", zebra_stripes=True, fixed_columns=1, **kw)
        self.store = store
        self.registry = registry  # read only: its guesses are a dict the capture thread writes

    def on_mount(self) -> None:
        for c in COLUMNS:
            self.add_column(c, key=c)
        self.update_rows()

    def update_rows(self) -> None:
        reg = self.registry
        guesses = dict(reg.guesses) if reg is not None else None  # dict() copies under the GIL
        given = dict(reg.devices) if reg is not None else None
        for st in self.store.unit_rows():
            cells = unit_cells(st, self.store.t0_ns, guesses, given)
            key = str(st.unit)
            if key in self.rows:
                for col, val in zip(COLUMNS[1:], cells[1:]):
                    self.update_cell(key, col, val)
            else:
                self.add_row(*cells, key=key)
