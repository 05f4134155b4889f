"""What the plot draws, free of Textual: the plotted registers, the time window, axes and the braille raster.

Registers are drawn as steps over capture time (a value holds until the next
sample).  Each series is first reduced to the plot's pixel columns (two per
character cell): the minimum and maximum of the samples in a column, joined to
the value carried in from the left, so drawing costs the same for 100 samples or
8,192 (the most a register keeps, history.py).

Units: the series are grouped by engineering unit in the order they were added.
The first unit has the left y axis, the second the right one; a series of any
further unit is scaled to the plot's height on its own and the legend gives its
real minimum and maximum.  The axes' steps and labels are plotaxis.py's.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from sniffer.tui.plotaxis import nice_step, tick_text, ticks, time_ticks
from sniffer.tui.timebase import TimeBase

PALETTE = ("bright_cyan", "yellow", "bright_magenta", "bright_green", "dark_orange", "bright_blue", "bright_red",
           "white")
MIN_SPAN_NS = 1_000_000  # zooming stops at a millisecond across
LEFT_W = 9  # left axis: 8 characters of labels and the axis line
RIGHT_W = 9
# a braille cell is 2 dots wide and 4 high: the bit of dot (x, y)
_DOT = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
# the dots of column dx from row a to row b of a cell, at once: _RUN[dx][a][b]
_RUN = tuple(tuple(tuple(sum(_DOT[d][dx] for d in range(a, b + 1)) for b in range(4)) for a in range(4))
             for dx in range(2))
_AXIS, _CURSOR = "grey62", "on grey23"


class PlotSet:
    """The registers being plotted, in order, each with its colour, and the one chosen (legend / Enter)."""

    def __init__(self, limit: int = len(PALETTE)) -> None:
        self.keys: list[tuple[int, str, int]] = []
        self.colours: dict[tuple[int, str, int], str] = {}
        self.limit = limit
        self.chosen = 0  # position in keys
        self.version = 0  # bumped on every change

    def __contains__(self, key) -> bool:
        return key in self.colours

    def __len__(self) -> int:
        return len(self.keys)

    def add(self, key) -> bool:
        """Plot `key` (False: it is already plotted or the palette is used up)."""
        if key in self.colours or len(self.keys) >= self.limit:
            return False
        used = set(self.colours.values())
        self.colours[key] = next(c for c in PALETTE if c not in used)
        self.keys.append(key)
        self.chosen = len(self.keys) - 1
        self.version += 1
        return True

    def remove(self, key) -> None:
        if key in self.colours:
            self.keys.remove(key)
            del self.colours[key]
            self.chosen = min(self.chosen, max(len(self.keys) - 1, 0))
            self.version += 1

    def only(self, key) -> None:
        """Plot just this register (None: nothing)."""
        if self.keys != ([key] if key is not None else []):
            self.keys, self.colours, self.chosen = [], {}, 0
            if key is not None:
                self.add(key)
            self.version += 1

    def choose(self, step: int) -> None:
        if self.keys:
            self.chosen = (self.chosen + step) % len(self.keys)
            self.version += 1

    @property
    def chosen_key(self):
        return self.keys[self.chosen] if self.keys else None


class TimeWindow:
    """The visible time range: everything, or `span` ns ending at `end` (None: the capture's end, following
    the tail as frames arrive)."""

    def __init__(self) -> None:
        self.span: float | None = None
        self.end: float | None = None

    @property
    def following(self) -> bool:
        return self.end is None

    def range(self, lo_all: float, hi_all: float) -> tuple[float, float]:
        if self.span is None or self.span >= hi_all - lo_all:
            return lo_all, hi_all
        end = hi_all if self.end is None else max(min(self.end, hi_all), lo_all + self.span)
        return end - self.span, end

    def reset(self) -> None:
        self.span = self.end = None

    def zoom(self, factor: float, around: float | None, lo_all: float, hi_all: float) -> None:
        """Span times `factor`, the time `around` staying where it is on screen (None: the centre, or the
        end while following)."""
        lo, hi = self.range(lo_all, hi_all)
        span = max((hi - lo) * factor, MIN_SPAN_NS)
        if span >= hi_all - lo_all:
            self.reset()
            return
        if around is None or not lo <= around <= hi:
            around = hi if self.following else (lo + hi) / 2
        new_lo = around - (around - lo) / (hi - lo) * span
        new_lo = min(max(new_lo, lo_all), hi_all - span)
        self.span = span
        self.end = None if new_lo + span >= hi_all else new_lo + span

    def pan(self, fraction: float, lo_all: float, hi_all: float) -> None:
        """Move by `fraction` of the span (negative: back in time); reaching the end follows the tail."""
        if self.span is None:
            return
        lo, hi = self.range(lo_all, hi_all)
        end = min(max(hi + fraction * self.span, lo_all + self.span), hi_all)
        self.end = None if end >= hi_all else end


def column_ranges(series, lo: float, hi: float, columns: int) -> list[tuple[float, float] | None]:
    """Per pixel column of [lo, hi): (min, max) of the step line through the series' samples, None where
    it has no value (before its first sample, after its latest)."""
    t, v = series.t, series.v
    out: list[tuple[float, float] | None] = [None] * columns
    if not t or columns <= 0 or hi <= lo:
        return out
    dt = (hi - lo) / columns
    i = bisect.bisect_left(t, lo)
    carry = v[i - 1] if i else None
    n, end = len(t), series.end[0]
    for c in range(columns):
        c_hi = lo + (c + 1) * dt
        j = bisect.bisect_left(t, c_hi, i, n)
        if j > i:
            seg = v[i:j]
            a, b = min(seg), max(seg)
            if carry is not None:
                a, b = min(a, carry), max(b, carry)
            out[c] = (a, b)
            carry, i = v[j - 1], j
        elif carry is not None:
            if lo + c * dt > end:
                break
            out[c] = (carry, carry)
    return out


@dataclass
class Trace:
    """One plotted register as the plot needs it."""

    key: tuple[int, str, int]
    label: str
    unit: str
    colour: str
    series: object  # history.Series


@dataclass
class Axis:
    unit: str
    lo: float
    hi: float
    step: float
    side: str  # "left", "right" or "scaled"


@dataclass
class PlotImage:
    """A drawn plot: lines of (text, style) runs, and what a click or the legend needs to know."""

    lines: list[list[tuple[str, str]]]
    x0: int  # first column of the plot area
    cols: int  # its width in cells
    top: int  # first line of the plot area
    rows: int
    lo: float  # the time range drawn (ns)
    hi: float
    axes: list[Axis]  # per trace
    extents: list[list[tuple[float, float] | None]]  # per trace, per pixel column
    spans: list[list[tuple[int, int] | None]]  # per trace, per cell column: (top, bottom) cell rows drawn

    def time_at(self, x: int) -> float:
        """The time at the middle of the cell column x (screen column of the widget)."""
        return self.lo + (x - self.x0 + 0.5) * (self.hi - self.lo) / self.cols

    def column_of(self, t_ns: float) -> int | None:
        c = math.floor((t_ns - self.lo) / (self.hi - self.lo) * self.cols)
        return c if 0 <= c < self.cols else None

    def trace_at(self, x: int, y: int) -> int | None:
        """The trace drawn nearest to screen cell (x, y) in its column (the last drawn wins a tie)."""
        c, r = x - self.x0, y - self.top
        if not 0 <= c < self.cols:
            return None
        best, best_d = None, None
        for i, spans in enumerate(self.spans):
            s = spans[c]
            if s is None:
                continue
            d = 0 if s[0] <= r <= s[1] else min(abs(r - s[0]), abs(r - s[1]))
            if best_d is None or d <= best_d:
                best, best_d = i, d
        return best


def _axes(traces: list[Trace], extents, rows: int) -> list[Axis]:
    """An axis per trace: the first two units share the left and right axes, others scale alone."""
    positions = _unit_positions(traces)
    ranges: dict[object, list[float]] = {}
    for i, pos in enumerate(positions):
        r = ranges.setdefault(pos if pos < 2 else -1 - i, [math.inf, -math.inf])
        for e in extents[i]:
            if e is not None:
                r[0], r[1] = min(r[0], e[0]), max(r[1], e[1])
    axes = []
    for i, (tr, pos) in enumerate(zip(traces, positions)):
        lo, hi = ranges[pos if pos < 2 else -1 - i]
        if lo > hi:
            lo, hi = 0.0, 1.0
        if lo == hi:
            pad = abs(lo) * 0.05 or 1.0
            lo, hi = lo - pad, hi + pad
        step = nice_step(hi - lo, max(rows // 3, 1))
        lo, hi = math.floor(lo / step + 1e-9) * step, math.ceil(hi / step - 1e-9) * step
        axes.append(Axis(tr.unit, lo, hi, step, ("left", "right")[pos] if pos < 2 else "scaled"))
    return axes


def render(traces: list[Trace], lo: float, hi: float, width: int, height: int, base: TimeBase,
           cursor_ns: float | None = None) -> PlotImage:
    """The plot of `traces` over [lo, hi) in a width x height cell box (the last trace is drawn on top), its
    time axis in the frame list's time base `base`."""
    right = 1 in _unit_positions(traces)
    x0 = LEFT_W
    cols = max(width - LEFT_W - (RIGHT_W if right else 1), 1)
    top, rows = 1, max(height - 3, 1)
    px, py = cols * 2, rows * 4
    extents = [column_ranges(tr.series, lo, hi, px) for tr in traces]
    axes = _axes(traces, extents, rows)
    bits = [[0] * cols for _ in range(rows)]
    owner = [[-1] * cols for _ in range(rows)]
    spans: list[list[tuple[int, int] | None]] = []
    for i, (ext, ax) in enumerate(zip(extents, axes)):
        scale = (py - 1) / (ax.hi - ax.lo)
        cell_spans: list[tuple[int, int] | None] = [None] * cols
        for x, e in enumerate(ext):
            if e is None:
                continue
            y_top = min(max(round((ax.hi - e[1]) * scale), 0), py - 1)
            y_bot = min(max(round((ax.hi - e[0]) * scale), 0), py - 1)
            cx, run = x >> 1, _RUN[x & 1]
            c_top, c_bot = y_top >> 2, y_bot >> 2
            for cy in range(c_top, c_bot + 1):  # a cell's dots of the span at once
                bits[cy][cx] |= run[y_top & 3 if cy == c_top else 0][y_bot & 3 if cy == c_bot else 3]
                owner[cy][cx] = i
            s = cell_spans[cx]
            cell_spans[cx] = (y_top // 4, y_bot // 4) if s is None else (min(s[0], y_top // 4), max(s[1], y_bot // 4))
        spans.append(cell_spans)
    image = PlotImage([], x0, cols, top, rows, lo, hi, axes, extents, spans)
    cursor = image.column_of(cursor_ns) if cursor_ns is not None else None
    left = next((a for a in axes if a.side == "left"), None)
    right_ax = next((a for a in axes if a.side == "right"), None)
    lines = image.lines
    lines.append([(f"{_unit_text(left):>{LEFT_W - 1}} ", _AXIS), (" " * cols, ""),
                  ((f" {_unit_text(right_ax)}" if right_ax else "").ljust(RIGHT_W if right else 1), _AXIS)])
    left_labels, right_labels = _y_labels(left, rows), _y_labels(right_ax, rows)
    for r in range(rows):
        line = [(f"{left_labels.get(r, ''):>{LEFT_W - 1}}" + ("┤" if r in left_labels else "│"), _AXIS)]
        run, style = [], None
        for c in range(cols):
            st = traces[owner[r][c]].colour if owner[r][c] >= 0 else ""
            if c == cursor:
                st = f"{st} {_CURSOR}".strip()
            if st != style and run:
                line.append(("".join(run), style))
                run = []
            style = st
            run.append(chr(0x2800 + bits[r][c]) if bits[r][c] else " ")
        line.append(("".join(run), style))
        if right:
            line.append((("├" if r in right_labels else "│") + f"{right_labels.get(r, ''):<{RIGHT_W - 1}}", _AXIS))
        else:
            line.append((" ", ""))
        lines.append(line)
    lines.extend(_time_axis(image, base, right))
    return image


def _unit_positions(traces: list[Trace]) -> list[int]:
    units: list[str] = []
    out = []
    for tr in traces:
        if tr.unit not in units:
            units.append(tr.unit)
        out.append(units.index(tr.unit))
    return out


def _unit_text(ax: Axis | None) -> str:
    return "" if ax is None else (ax.unit or "no unit")[:LEFT_W - 1]


def _y_labels(ax: Axis | None, rows: int) -> dict[int, str]:
    """{cell row: tick label} of an axis (a tick at the row its value is drawn on)."""
    if ax is None:
        return {}
    py = rows * 4
    out = {}
    for v in ticks(ax.lo, ax.hi, ax.step):
        r = round((ax.hi - v) * (py - 1) / (ax.hi - ax.lo)) // 4
        out.setdefault(r, tick_text(v, ax.step))
    return out


def _time_axis(image: PlotImage, base: TimeBase, right: bool) -> list[list[tuple[str, str]]]:
    """The x axis line with tick marks and the labels under it, in the frame list's time base."""
    cols = image.cols
    marks = ["─"] * cols
    labels = [" "] * (cols + RIGHT_W)
    points, unit = time_ticks(base, image.lo, image.hi, max(cols // 14, 1))
    for t, text in points:
        c = image.column_of(t)
        if c is None:
            continue
        marks[c] = "┬"
        at = max(c - len(text) // 2, 0)
        if all(ch == " " for ch in labels[max(at - 1, 0):at + len(text) + 1]):
            labels[at:at + len(text)] = text
    tail = RIGHT_W if right else 1
    return [[(" " * (LEFT_W - 1) + "└" + "".join(marks) + ("┘" if right else "─") + " " * (tail - 1), _AXIS)],
            [(" " * LEFT_W + "".join(labels[:cols + tail - 2]) + f" {unit}", _AXIS)]]
