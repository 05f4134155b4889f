"""The TUI's model: every frame seen, index arrays for filters, per-unit stats.

Free of Textual (toolong keeps its App thin and its model plain): the store is
driven by `add(frames)` from the UI thread (the sink buffers frames from the
capture thread, see `sink.py`) and unit-tested without a terminal.

Rows are positions in `frames` (arrival order); `Frame.index` / `Frame.pair`
are the pipeline's numbers, mapped to rows with `row_of`.  The view is an
`array` of rows that pass the filter, appended to as frames arrive, so a
million frames cost a few MB of index, not a widget row each.
"""

from __future__ import annotations

import bisect
import statistics
from array import array
from collections import deque
from dataclasses import dataclass, field

from ..codes import Annotation
from ..frame import Frame

# per-frame flag bits
F_ERROR = 1  # an error annotation or bad CRC
F_WARN = 2  # a warning annotation
F_EXC = 4  # exception response
F_TIMEOUT = 8  # request without (timely) response
F_NOISE = 16
F_PROBLEM = F_ERROR | F_WARN | F_EXC | F_TIMEOUT | F_NOISE

TIMEOUT_CODES = frozenset({"pair.timeout", "pair.no_response"})
ROLES = ("request", "response", "unknown", "noise")
_LAT_KEEP = 2048  # latencies kept per unit for the median
_RATE_WINDOW_NS = 10_000_000_000  # poll rate over the last 10 s of capture time
_HISTORY = 120  # values kept per register for the sparkline
# which Modbus table a function's points live in
TABLE_OF = {1: "coil", 5: "coil", 15: "coil", 2: "discrete", 3: "holding", 6: "holding", 16: "holding",
            23: "holding", 4: "input"}


def frame_flags(f: Frame) -> int:
    fl = 0
    if f.protocol == "noise":
        fl |= F_NOISE
    if f.crc_ok is False:
        fl |= F_ERROR
    if f.exception:
        fl |= F_EXC
    for a in f.annotations:
        if a.severity == "error":
            fl |= F_ERROR
        elif a.severity == "warning":
            fl |= F_WARN
        if a.code in TIMEOUT_CODES:
            fl |= F_TIMEOUT
    return fl


def frame_from_record(rec: dict, t0_ns: int = 0) -> Frame:
    """A Frame back from its JSON record (the inverse of records.frame_record, as far as it goes)."""
    raw = bytes.fromhex(rec["raw"])
    f = Frame(rec.get("index", 0), t0_ns + round(rec["t"] * 1e9), t0_ns + round(rec.get("t_end", rec["t"]) * 1e9),
              raw, rec["protocol"], rec.get("unit"), rec.get("function"), crc_ok=rec.get("crc_ok"),
              crc_expected=None if rec.get("crc_expected") is None else int(rec["crc_expected"], 16),
              time_source=rec.get("time_source", "byte"), noise_reason=rec.get("noise_reason"),
              channel=rec.get("channel", ""))
    f.role = rec.get("role", f.role)
    f.pair, f.latency_ms, f.model = rec.get("pair"), rec.get("latency_ms"), rec.get("model")
    f.points, f.exception, f.summary = rec.get("points") or [], rec.get("exception"), rec.get("summary", "")
    f.annotations = [Annotation(a["code"], a["severity"], a["detail"], a["span"][0], a["span"][1])
                     for a in rec.get("annotations") or []]
    return f


@dataclass
class Filter:
    units: frozenset[int] | None = None
    functions: frozenset[int] | None = None
    roles: frozenset[str] | None = None
    errors_only: bool = False
    text: str = ""

    @property
    def active(self) -> bool:
        return bool(self.units is not None or self.functions is not None or self.roles is not None
                    or self.errors_only or self.text)

    def describe(self) -> str:
        parts = []
        if self.units is not None:
            parts.append("unit " + ",".join(map(str, sorted(self.units))))
        if self.functions is not None:
            parts.append("fc " + ",".join(f"{x:02X}" for x in sorted(self.functions)))
        if self.roles is not None:
            parts.append("role " + ",".join(sorted(self.roles)))
        if self.errors_only:
            parts.append("errors")
        if self.text:
            parts.append(f"/{self.text}")
        return " ".join(parts) or "none"


@dataclass
class UnitStats:
    unit: int
    model: str | None = None
    requests: int = 0
    responses: int = 0
    crc_errors: int = 0
    exceptions: int = 0
    timeouts: int = 0
    lat_min: float | None = None
    lat_max: float | None = None
    latencies: deque = field(default_factory=lambda: deque(maxlen=_LAT_KEEP))
    recent_requests: deque = field(default_factory=deque)  # t_ns of requests in the rate window
    last_seen_ns: int = 0

    @property
    def lat_median(self) -> float | None:
        return statistics.median(self.latencies) if self.latencies else None

    @property
    def poll_rate(self) -> float:
        """Requests per second over the last window of capture time."""
        r = self.recent_requests
        if len(r) < 2:
            return 0.0
        span = (r[-1] - r[0]) / 1e9
        return (len(r) - 1) / span if span > 0 else 0.0


@dataclass
class RegisterValue:
    unit: int
    table: str
    address: int
    name: str
    value: object
    raw: object
    eng_unit: str | None
    text: str
    t_ns: int
    changed_ns: int
    changes: int = 0
    history: deque = field(default_factory=lambda: deque(maxlen=_HISTORY))


def _matches_text(f: Frame, needle: str) -> bool:
    """Free-text search over what a row and its detail show: summary, codes, details, model, hex."""
    if needle in f.summary.lower():
        return True
    for a in f.annotations:
        if needle in a.code or needle in a.detail.lower():
            return True
    return (needle in f.raw.hex() or needle in (f.model or "") or needle in (f.noise_reason or "").lower()
            or needle == f.role)


class FrameStore:
    """All frames of a capture plus what the views need to find them quickly."""

    def __init__(self, t0_ns: int = 0) -> None:
        self.t0_ns = t0_ns
        self.frames: list[Frame] = []
        self.flags = array("B")
        self.row_of: dict[int, int] = {}  # Frame.index -> row
        self.filter = Filter()
        self.view = array("q")  # rows passing the filter (up to the pause point)
        self.problems = array("q")  # rows with any problem flag (unfiltered)
        self.units: dict[int, UnitStats] = {}
        self.registers: dict[tuple[int, int], RegisterValue] = {}
        self.bookmarks: set[int] = set()
        self.paused_at: int | None = None  # row count when the view was paused
        self.bytes_total = 0
        self.noise_bytes = 0
        self.generation = 0  # bumped on every change the views must redraw for

    # ------------------------------------------------------------- intake
    def __len__(self) -> int:
        return len(self.frames)

    def add(self, frames) -> int:
        """Append settled frames (UI thread); returns how many were added."""
        n = 0
        for f in frames:
            self._add_one(f)
            n += 1
        if n:
            self.generation += 1
        return n

    def add_records(self, records) -> int:
        """Append JSONL / MCAP `/frames` records (sniffer.records.frame_record) as frames."""
        return self.add(frame_from_record(r, self.t0_ns) for r in records)

    def _add_one(self, f: Frame) -> None:
        row = len(self.frames)
        fl = frame_flags(f)
        self.frames.append(f)
        self.flags.append(fl)
        self.row_of[f.index] = row
        self.bytes_total += len(f.raw)
        if fl & F_NOISE:
            self.noise_bytes += len(f.raw)
        if fl & F_PROBLEM:
            self.problems.append(row)
        if self.paused_at is None and self._passes(f, fl):
            self.view.append(row)
        if f.unit is not None and f.protocol != "noise":
            self._unit_stats(f, fl)
            if f.points:
                self._registers(f)

    def _unit_stats(self, f: Frame, fl: int) -> None:
        st = self.units.get(f.unit)
        if st is None:
            st = self.units[f.unit] = UnitStats(f.unit)
        if f.model:
            st.model = f.model
        st.last_seen_ns = f.t_ns
        if f.role == "request":
            st.requests += 1
            r = st.recent_requests
            r.append(f.t_ns)
            while r and f.t_ns - r[0] > _RATE_WINDOW_NS:
                r.popleft()
        elif f.role == "response":
            st.responses += 1
        if f.crc_ok is False:
            st.crc_errors += 1
        if fl & F_EXC:
            st.exceptions += 1
        if fl & F_TIMEOUT:
            st.timeouts += 1
        lat = f.latency_ms
        if lat is not None and f.role == "response":
            st.latencies.append(lat)
            st.lat_min = lat if st.lat_min is None else min(st.lat_min, lat)
            st.lat_max = lat if st.lat_max is None else max(st.lat_max, lat)

    def _registers(self, f: Frame) -> None:
        if f.crc_ok is False or f.exception:
            return
        table = TABLE_OF.get(f.function, "other") if f.function is not None else "other"
        for p in f.points:
            addr = p.get("address")
            if addr is None:
                continue
            key = (f.unit, table, addr)
            value = p.get("value")
            rv = self.registers.get(key)
            if rv is None:
                rv = self.registers[key] = RegisterValue(
                    f.unit, table, addr, p.get("name", ""), value, p.get("raw"), p.get("unit"), p.get("text") or "",
                    f.t_ns, f.t_ns)
            else:
                if rv.value != value:
                    rv.changed_ns = f.t_ns
                    rv.changes += 1
                rv.value, rv.raw, rv.t_ns = value, p.get("raw"), f.t_ns
                rv.name, rv.eng_unit, rv.text = p.get("name", rv.name), p.get("unit"), p.get("text") or ""
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                rv.history.append(float(value))

    # ------------------------------------------------------------- filters
    def _passes(self, f: Frame, fl: int) -> bool:
        flt = self.filter
        if not flt.active:
            return True
        if flt.errors_only and not fl & F_PROBLEM:
            return False
        if flt.units is not None and f.unit not in flt.units:
            return False
        if flt.functions is not None and (f.function is None or (f.function & 0x7F) not in flt.functions):
            return False
        if flt.roles is not None and f.role not in flt.roles:
            return False
        return not flt.text or _matches_text(f, flt.text)

    def set_filter(self, flt: Filter) -> None:
        flt.text = flt.text.lower()
        self.filter = flt
        self._rebuild()

    def update_filter(self, **kw) -> Filter:
        d = dict(self.filter.__dict__)
        d.update(kw)
        self.set_filter(Filter(**d))
        return self.filter

    def _rebuild(self) -> None:
        end = len(self.frames) if self.paused_at is None else self.paused_at
        frames, flags, passes = self.frames, self.flags, self._passes
        if not self.filter.active:
            self.view = array("q", range(end))
        else:
            self.view = array("q", (r for r in range(end) if passes(frames[r], flags[r])))
        self.generation += 1

    # ------------------------------------------------------------- pause
    @property
    def paused(self) -> bool:
        return self.paused_at is not None

    def pause(self, on: bool | None = None) -> bool:
        """Freeze the view (capture and stats go on); resuming catches up."""
        on = not self.paused if on is None else on
        if on and self.paused_at is None:
            self.paused_at = len(self.frames)
        elif not on and self.paused_at is not None:
            self.paused_at = None
            self._rebuild()
        self.generation += 1
        return self.paused

    # ------------------------------------------------------------- lookup
    def frame_at(self, pos: int) -> Frame:
        """The frame at position `pos` of the view."""
        return self.frames[self.view[pos]]

    def pos_of_row(self, row: int) -> int | None:
        """Position of a row in the view, or None if filtered out."""
        i = bisect.bisect_left(self.view, row)
        return i if i < len(self.view) and self.view[i] == row else None

    def nearest_pos(self, row: int) -> int:
        return min(bisect.bisect_left(self.view, row), max(len(self.view) - 1, 0))

    def pair_row(self, row: int) -> int | None:
        p = self.frames[row].pair
        return None if p is None else self.row_of.get(p)

    def next_problem(self, row: int, forward: bool = True) -> int | None:
        """The next (previous) row with a problem, after (before) `row`, within the view's range."""
        end = len(self.frames) if self.paused_at is None else self.paused_at
        pr = self.problems
        if forward:
            i = bisect.bisect_right(pr, row)
            while i < len(pr) and pr[i] < end:
                if self.pos_of_row(pr[i]) is not None:
                    return pr[i]
                i += 1
            return None
        i = bisect.bisect_left(pr, row) - 1
        while i >= 0:
            if pr[i] < end and self.pos_of_row(pr[i]) is not None:
                return pr[i]
            i -= 1
        return None

    def toggle_bookmark(self, row: int) -> bool:
        if row in self.bookmarks:
            self.bookmarks.discard(row)
            on = False
        else:
            self.bookmarks.add(row)
            on = True
        self.generation += 1
        return on

    def next_bookmark(self, row: int, forward: bool = True) -> int | None:
        marks = sorted(b for b in self.bookmarks if self.pos_of_row(b) is not None)
        if not marks:
            return None
        if forward:
            i = bisect.bisect_right(marks, row)
            return marks[i] if i < len(marks) else None
        i = bisect.bisect_left(marks, row) - 1
        return marks[i] if i >= 0 else None

    def unit_rows(self) -> list[UnitStats]:
        return [self.units[u] for u in sorted(self.units)]

    def register_rows(self, unit: int | None = None) -> list[RegisterValue]:
        """Latest decoded value per (unit, table, address): the register shadow with names and units."""
        keys = sorted(k for k in self.registers if unit is None or k[0] == unit)
        return [self.registers[k] for k in keys]
