"""The plot tab: registers over capture time, overlaid, with a legend; zoom, pan, a cursor, and a
click (or Enter at the cursor) that goes to the frame of the nearest sample.

`PlotView` draws a PlotSet's registers (plotmodel.py does the drawing; this is
the widget: keys, mouse, redraw only when what it shows changed).  The
Registers tab uses one for its highlighted register; `PlotPane` is tab 5: the
legend over a PlotView of the registers added with `a` in the Registers tab.
"""

from __future__ import annotations

import bisect
from typing import ClassVar

from rich.segment import Segment
from rich.style import Style
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.message import Message
from textual.strip import Strip
from textual.widget import Widget
from textual.widgets import DataTable, Static

from sniffer.tui.store import FrameStore
from sniffer.tui.plotaxis import time_unit
from sniffer.tui.plotmodel import PlotImage, PlotSet, TimeWindow, Trace, render

EMPTY = "nothing plotted: in the Registers tab (3) press a on a register to add it here"
# the legend's columns and their widths (fixed: the rows are filled again as the view changes)
LEGEND = (("", 6), ("unit", 4), ("register", 44), ("axis", 10), ("min", 10), ("max", 10), ("at cursor", 14))


class JumpToFrame(Message):
    """Show the frame with this Frame.index in the Frames tab."""

    def __init__(self, index: int) -> None:
        self.index = index
        super().__init__()


def number(v: float) -> str:
    return f"{v:.10g}"


class PlotView(Widget, can_focus=True):
    """Braille plot of the registers in `plots` (see the module doc)."""

    BINDINGS: ClassVar[list[Binding]] = [
        Binding("plus,equals_sign", "zoom(0.5)", "Zoom in"),
        Binding("minus", "zoom(2)", "Zoom out"),
        Binding("0", "reset", "All"),
        Binding("left", "pan(-0.25)", "Pan", show=False),
        Binding("right", "pan(0.25)", "Pan", show=False),
        Binding("comma", "cursor(-1)", "Cursor", show=False),
        Binding("full_stop", "cursor(1)", "Cursor", show=False),
        Binding("up", "choose(-1)", "Choose", show=False),
        Binding("down", "choose(1)", "Choose", show=False),
        Binding("enter", "jump", "Go to frame"),
        Binding("d,delete", "remove", "Remove"),
    ]
    DEFAULT_CSS = "PlotView { height: 1fr; } PlotView:focus { background: $boost; }"

    class Drawn(Message):
        """The view was drawn again (the legend's ranges follow)."""

    def __init__(self, store: FrameStore, plots: PlotSet, *, removable: bool = True, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self.plots = plots
        self.removable = removable  # False: the Registers tab's plot of the highlighted register
        self.window = TimeWindow()
        self.cursor_ns: float | None = None
        self.image: PlotImage | None = None
        self.traces: list[Trace] = []
        self._drawn_for = None
        self._strips: list[Strip] = []
        self._styles: dict[str, Style] = {}

    # ------------------------------------------------------------ data
    def extent(self) -> tuple[float, float]:
        """The whole capture's time range (ns)."""
        lo = self.store.t0_ns
        return lo, max(self.store.last_t_ns, lo + 1_000_000_000)

    def time_range(self) -> tuple[float, float]:
        return self.window.range(*self.extent())

    def _traces(self) -> list[Trace]:
        regs, plots = self.store.registers, self.plots
        out = []
        for k in plots.keys:
            rv = regs.get(k)
            if rv is not None:
                out.append(Trace(k, f"u{rv.unit} {rv.name}", rv.eng_unit or "", plots.colours[k], rv.history))
        chosen = plots.chosen_key  # drawn last: on top
        return sorted(out, key=lambda tr: tr.key == chosen)

    def update_plot(self, force: bool = False) -> None:
        """Draw again if anything shown changed (the registers' samples, the window, the size, the cursor)."""
        traces = self._traces()
        lo, hi = self.time_range()
        w, h = self.size
        state = (self.plots.version, tuple((tr.series.seen, tr.series.thins) for tr in traces), lo, hi, w, h,
                 self.cursor_ns, self.store.time.version)
        if state == self._drawn_for and not force:
            return
        self._drawn_for = state
        self.traces = traces
        if not traces or w < 20 or h < 5:
            self.image = None
            lines = [[(EMPTY if self.removable else "", "grey62")]]
        else:
            self.image = render(traces, lo, hi, w, h - 1, self.store.time, self.cursor_ns)
            lines = self.image.lines + [[(self.info(), "")]]
        self._strips = [Strip([Segment(text, self._style(st)) for text, st in line]).crop_extend(0, w, None)
                        for line in lines]
        self.refresh()
        self.post_message(self.Drawn())

    def _style(self, name: str) -> Style:
        st = self._styles.get(name)
        if st is None:
            st = self._styles[name] = Style.parse(name) if name else Style()
        return st

    def info(self) -> str:
        """The line under the plot: the window, and the cursor's sample of the chosen register."""
        lo, hi = self.time_range()
        at = self.store.time.text  # the frame list's time base
        unit = time_unit(self.store.time, int(lo))
        text = f"{at(int(lo))}..{at(int(hi))} {unit}" + (" (following the tail)" if self.window.following else "")
        hit = self.cursor_sample()
        if hit is not None:
            tr, (t, v, ix) = hit
            value = f"{number(v)} {tr.unit}".strip()
            text += f" │ cursor {at(int(self.cursor_ns))} {unit}: {tr.label} {value} at #{ix} ({at(t)})"
        return text

    def cursor_sample(self):
        """(trace, (t_ns, value, frame index)) of the chosen register's sample nearest the cursor."""
        if self.cursor_ns is None:
            return None
        key = self.plots.chosen_key
        tr = next((tr for tr in self.traces if tr.key == key), None)
        hit = tr.series.nearest(self.cursor_ns) if tr is not None else None
        return None if hit is None else (tr, hit)

    def value_at(self, tr: Trace, t_ns: float) -> float | None:
        """The register's value in effect at t_ns (its latest sample at or before)."""
        s = tr.series
        i = bisect.bisect_right(s.t, t_ns)
        return s.v[i - 1] if i else None

    def render_line(self, y: int) -> Strip:
        if y >= len(self._strips):
            return Strip.blank(self.size.width, self.rich_style)
        return self._strips[y].apply_style(self.rich_style)

    def on_resize(self) -> None:
        self.update_plot()

    # ------------------------------------------------------------ keys and mouse
    def action_zoom(self, factor: float) -> None:
        self.window.zoom(factor, self.cursor_ns, *self.extent())
        self.update_plot()

    def action_reset(self) -> None:
        self.window.reset()
        self.update_plot()

    def action_pan(self, fraction: float) -> None:
        self.window.pan(fraction, *self.extent())
        self.update_plot()

    def action_cursor(self, step: int) -> None:
        lo, hi = self.time_range()
        cols = self.image.cols if self.image is not None else max(self.size.width, 1)
        cell = (hi - lo) / cols
        if self.cursor_ns is None or not lo <= self.cursor_ns < hi:
            self.cursor_ns = lo + (cols // 2 + 0.5) * cell
        else:
            self.cursor_ns = min(max(self.cursor_ns + step * cell, lo + cell / 2), hi - cell / 2)
        self.update_plot()

    def action_choose(self, step: int) -> None:
        self.plots.choose(step)
        self.update_plot()

    def action_remove(self) -> None:
        key = self.plots.chosen_key
        if self.removable and key is not None:
            self.plots.remove(key)
            self.update_plot()

    def action_jump(self) -> None:
        if self.cursor_ns is None:
            lo, hi = self.time_range()
            self.cursor_ns = (lo + hi) / 2
        hit = self.cursor_sample()
        if hit is None:
            self.notify("no sample to go to: add a register to the plot, move the cursor with , and .", timeout=3)
            return
        self.update_plot()
        self.post_message(JumpToFrame(hit[1][2]))

    def on_click(self, event) -> None:
        img = self.image
        if img is None or not img.x0 <= event.x < img.x0 + img.cols:
            return
        i = img.trace_at(event.x, event.y)
        if i is not None:
            self.plots.chosen = self.plots.keys.index(self.traces[i].key)
        self.cursor_ns = img.time_at(event.x)
        self.action_jump()

    def _scroll_zoom(self, event, factor: float) -> None:
        img = self.image
        if img is not None and img.x0 <= event.x < img.x0 + img.cols:
            self.window.zoom(factor, img.time_at(event.x), *self.extent())
            self.update_plot()
            event.stop()

    def on_mouse_scroll_up(self, event) -> None:
        self._scroll_zoom(event, 0.5)

    def on_mouse_scroll_down(self, event) -> None:
        self._scroll_zoom(event, 2.0)


class PlotPane(Vertical):
    """Tab 5: the legend (colour, register, axis, visible min / max, value at the cursor) over the plot."""

    DEFAULT_CSS = """
    PlotPane > #legend { height: auto; max-height: 10; }
    PlotPane > #plothelp { height: 1; color: $text-muted; padding: 0 1; }
    """

    def __init__(self, store: FrameStore, plots: PlotSet, **kw) -> None:
        super().__init__(**kw)
        self.store = store
        self.plots = plots
        self._rows: list[tuple] = []  # the legend's rows as shown

    def compose(self) -> ComposeResult:
        legend = DataTable(id="legend", cursor_type="row", zebra_stripes=True, show_cursor=False)
        legend.can_focus = False  # the plot keeps the keys; ↑/↓ there choose the row
        yield legend
        yield Static("+/- zoom  ←/→ pan  0 all  ,/. cursor  Enter or click: go to the frame  ↑/↓ choose  "
                     "d remove  (a in Registers adds)", id="plothelp")
        yield PlotView(self.store, self.plots, id="plotview")

    def on_mount(self) -> None:
        legend = self.query_one("#legend", DataTable)
        for c, width in LEGEND:
            legend.add_column(c, key=c or "colour", width=width)

    def update_plot(self) -> None:
        self.query_one("#plotview", PlotView).update_plot()

    def on_plot_view_drawn(self) -> None:
        self.fill_legend(self.query_one("#plotview", PlotView))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        """A click on a legend row chooses that register."""
        key = event.row_key.value if event.row_key is not None else None
        keys = [_row_key(k) for k in self.plots.keys]
        if key in keys and keys.index(key) != self.plots.chosen:
            self.plots.chosen = keys.index(key)
            self.query_one("#plotview", PlotView).update_plot()

    def fill_legend(self, view: PlotView) -> None:
        """One row per plotted register: colour (▶ the chosen one), unit, address and name, its axis, the
        minimum and maximum in view, the value at the cursor."""
        img, regs, chosen = view.image, self.store.registers, self.plots.chosen_key
        drawn = {tr.key: i for i, tr in enumerate(view.traces)}
        rows = []
        for k in self.plots.keys:
            rv = regs.get(k)
            if rv is None:
                continue
            cells = [Text(("▶ " if k == chosen else "  ") + "━━━", self.plots.colours[k]), str(rv.unit),
                     f"{rv.address_text} {rv.title}"[:48]]
            i = drawn.get(k)
            if img is None or i is None:
                rows.append((k, *cells, "", "", "", ""))
                continue
            ax, ext = img.axes[i], [e for e in img.extents[i] if e is not None]
            cells.append(f"{ax.side} {ax.unit}".strip() if ax.side != "scaled" else "own scale")
            cells += [number(min(e[0] for e in ext)), number(max(e[1] for e in ext))] if ext else ["", ""]
            v = view.value_at(view.traces[i], view.cursor_ns) if view.cursor_ns is not None else None
            cells.append("" if v is None else f"{number(v)} {rv.eng_unit or ''}".strip())
            rows.append((k, *cells))
        if rows != self._rows:
            self._rows = rows
            legend = self.query_one("#legend", DataTable)
            legend.clear()
            for k, *cells in rows:
                legend.add_row(*cells, key=_row_key(k))


def _row_key(key: tuple[int, str, int]) -> str:
    return f"{key[0]}:{key[1]}:{key[2]}"
