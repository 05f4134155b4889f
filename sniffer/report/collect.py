"""What a report shows, gathered as the frames pass through the capture session: flat memory.

    c = Collector(compare=True)
    c.begin(path, session)          # after session.open(): its settings, where it goes on the time axis
    for f in session: c.frame(f)
    c.end(session)                  # frames, bytes, damage; then the next capture, in order
    data = c.to_data()              # JSON-ready: what sniffer.report.page draws (its verdicts first)

Several captures make one report on one time axis: each capture's frames are moved
onto it as they pass (`Frame.t_ns` becomes ns from the report's start: nothing else
holds the frames).  When every capture knows its wall-clock start the axis is the
clock (a capture that would overlap the one before is put after it, and says so);
otherwise each capture follows the one before.

Every figure is bounded whatever the capture's length: counts over time in at most
1,024 buckets (buckets.py), per unit its figures (analysis/unitfigures.py: the counts and the latency
quantiles every view shows), a latency histogram and a thinned series (units.py), per
request type the poll period (polls.py), the register shadow's
history through the TUI's RegisterBook (analysis/register_book.py: the same values, names and
units the Registers tab shows, at most REGISTER_POINTS samples a register; a register
whose values changed model, name or unit is one series per each, never one line
across units), the writes and faults (timeline.py), the findings of `sniffer diagnose`
(sniffer.diagnose: the page opens with them), and with `compare` the semantic summary
`sniffer diff` makes (analysis.diff.Summary).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import math
import os
from collections import Counter

from decoders.registry import code_book
from sniffer import codes as C
from sniffer.frame import LinkUnit
from sniffer.diagnose import Diagnosis
from sniffer.analysis.diff import Summary
from sniffer.analysis.register_book import RegisterBook
from sniffer.report.buckets import TimeBuckets
from sniffer.report.polls import Polls
from sniffer.report.timeline import Timeline
from sniffer.analysis.unitfigures import UnitBook, unit_name
from sniffer.report.units import UnitAgg, latency_edges, series_points, turnaround_edges

COLUMNS = ("frames", "busy_ns", "crc", "exceptions", "timeouts", "retries", "noise", "gaps", "t15", "t35", "writes",
           "faults", "fast35", "fast15")  # fast35/15: responses under 3.5 / 1.5 characters after their request
# the series a code's category counts in: a frame once in timeouts, retries, faults and exceptions (the unit
# figures' counts, over time); every annotation in the others
_COLUMN_OF = {C.TIMEOUT_CAT: "timeouts", C.RETRY_CAT: "retries", C.FAULT_CAT: "faults", C.ALARM_CAT: "faults",
              C.EXCEPTION_CAT: "exceptions", C.NOISE_CAT: "noise", C.GAP_CAT: "gaps", C.T15_CAT: "t15",
              C.T35_CAT: "t35"}
CODE_COLUMN = {code: _COLUMN_OF[cat] for code, cat in code_book().categories.items() if cat in _COLUMN_OF}
_ONCE = frozenset({"timeouts", "retries", "faults", "exceptions"})
PLOTTED_UNITS = 16  # units in the latency and turnaround plots (the most answers); all are in the units table
REGISTER_POINTS = 1024  # history kept per register (analysis.history thins beyond)
REGISTER_RETIRED = 64  # earlier series of registers kept (a value named or scaled otherwise before)
REGISTER_PLOTS = 40  # (unit, engineering unit) groups plotted; the rest are in the table
SERIES_PER_PLOT = 8


def _iso(wall_ns: int) -> str | None:
    if wall_ns <= 0:
        return None
    return _dt.datetime.fromtimestamp(wall_ns / 1e9, _dt.timezone.utc).isoformat(timespec="milliseconds")


def _timing(line) -> tuple[int, float, float]:
    """(character time in ns, t1.5 and t3.5 in characters) of a line."""
    return line.char_ns, line.t15_ns / line.char_ns, line.t35_ns / line.char_ns


def _split(unit) -> tuple[str, int]:
    """(link, unit) of a register book's unit (`frame.unit_key`: a number, or a LinkUnit with several links)."""
    return (unit.link, unit.unit) if isinstance(unit, LinkUnit) else ("", unit)


def file_facts(path: str) -> dict:
    """Size, modification time and SHA-256 of a capture file (read in blocks); of a rotated capture's
    folder the files in it and their total size."""
    if os.path.isdir(path):
        sizes = [e.stat().st_size for e in os.scandir(path) if e.is_file()]
        return {"size": sum(sizes), "files": len(sizes)}
    h = hashlib.sha256()
    try:
        st = os.stat(path)
        with open(path, "rb") as f:
            while block := f.read(1 << 20):
                h.update(block)
    except OSError:
        return {}
    return {"size": st.st_size, "modified": _iso(int(st.st_mtime * 1e9)), "sha256": h.hexdigest()}


class Collector:
    """Everything a report shows (see the module doc)."""

    def __init__(self, compare: bool = False) -> None:
        self.captures: list[dict] = []
        self.buckets = TimeBuckets(COLUMNS)
        self.figures = UnitBook()  # every unit's figures (unitfigures: as every view counts them)
        self.units: dict[tuple, UnitAgg] = {}  # (link, unit) -> the figures and what the report draws besides
        self.polls = Polls()
        self.book = RegisterBook(history_cap=REGISTER_POINTS, retired=REGISTER_RETIRED)
        self.timeline = Timeline()
        self.codes: Counter = Counter()
        self.time_sources: Counter = Counter()  # responses with a latency, by how their times were taken
        self.summary = Summary() if compare else None
        self.diagnosis = Diagnosis()  # on the report's time axis: its findings' times are the page's
        self.clock = True  # the axis is the wall clock (every capture knows its start)
        self.origin_wall = 0
        self.end_ns = 0  # the latest time on the axis
        self._shift = 0
        self._char_ns = 0
        self._t15 = self._t35 = 0.0
        self._lines: dict[str, tuple[int, float, float]] = {}  # link -> _timing of its line
        self._capture = -1

    # ------------------------------------------------------------ captures
    def begin(self, label: str, session) -> None:
        """A capture starts (its session opened): place it on the axis."""
        info, resolved = session.info, session.resolved
        wall = info.wall_anchor_ns or 0
        note = None
        start = self.end_ns
        if not self.captures:
            self.clock, self.origin_wall, start = wall > 0, wall, 0
        elif wall <= 0:
            self.clock = False
        elif self.clock:
            at = wall - self.origin_wall
            if at < start:
                note = "its clock overlaps the capture before: placed after it"
            start = max(start, at)
        self._shift = start - info.t0_ns
        self.diagnosis.start_session(session)
        self.diagnosis.t0_ns = 0
        self.polls.new_capture()
        self.timeline.new_capture()
        # several links: each its own line settings (sniffer.capture.links.LinkPipelines.resolved)
        by_link = getattr(getattr(session, "pipeline", None), "resolved", None) or {"": resolved}
        self._lines = {name: _timing(r.line) for name, r in by_link.items()}
        self._char_ns, self._t15, self._t35 = self._lines.get("") or next(iter(self._lines.values()))
        self._capture = len(self.captures)
        links = [{"name": name, "line": r.line.label(), "protocol": r.protocol.name,
                  "devices": {str(u): m for u, m in sorted(r.devices.items())}}
                 for name, r in by_link.items() if name]
        self.captures.append({
            "label": label, "path": os.path.abspath(getattr(session.source, "path", label)),
            **file_facts(getattr(session.source, "path", label)),
            "source": info.source, "port": info.port, "line": resolved.line.label(),
            "protocol": resolved.protocol.name, "settings": resolved.describe(),
            "timeout_ms": resolved.timeout_ms,
            "unit_timeouts": {str(u): ms for u, ms in sorted(resolved.unit_timeouts.items())},
            "model_files": list(resolved.model_files), "bus_file": session.spec.bus_file if session.spec else None,
            "devices": {str(u): m for u, m in sorted(resolved.devices.items())}, "time_source": info.time_source,
            "limits": [list(x) for x in sorted({(round(a, 3), round(b, 3)) for _, a, b in self._lines.values()})],
            "low_latency": info.low_latency, "recorded_by": info.sniffer_version,
            "start_wall": _iso(wall), "start_s": start / 1e9, "note": note,
            "extra": {k: v for k, v in info.extra.items() if isinstance(v, (str, int, float, bool))},
            "links": links,
        })

    def end(self, session) -> None:
        """The capture ended: what it held, what went wrong, the units' models the registry settled on."""
        c = self.captures[-1]
        c.update(frames=session.frames_out, bytes=session.bytes_in, noise_bytes=session.noise_bytes,
                 damage=session.damage, error=session.error, end_s=self.end_ns / 1e9,
                 duration_s=round(self.end_ns / 1e9 - c["start_s"], 6))
        regs = getattr(getattr(session, "pipeline", None), "registries", None) or {"": session.registry}
        for link, reg in regs.items():
            if reg is None:
                continue
            given = dict(reg.devices)
            for unit, g in dict(reg.guesses).items():
                u = self.units.get((link, unit))
                if u is not None and unit not in given:
                    u.model = f"{g[0]} (guess {g[1]:.0%})"
            for unit, model in given.items():
                if (link, unit) in self.units:
                    self.units[(link, unit)].model = f"{model} (given)"

    # ------------------------------------------------------------ frames
    def frame(self, f) -> None:
        """One decoded frame, in order (moved onto the report's axis here)."""
        f.t_ns += self._shift
        f.t_end_ns += self._shift
        x = f.t_ns
        if f.t_end_ns > self.end_ns:
            self.end_ns = f.t_end_ns
        b = self.buckets.index(x)
        cols = self.buckets.cols
        cols["frames"][b] += 1
        cols["busy_ns"][b] += len(f.raw) * (self._lines[f.link][0] if f.link else self._char_ns)
        if f.crc_ok is False:
            cols["crc"][b] += 1
        codes = self.codes
        once = None
        for a in f.annotations:
            codes[a.code] += 1
            col = CODE_COLUMN.get(a.code)
            if col is not None:
                if col in _ONCE:
                    once = {col} if once is None else once | {col}
                else:
                    cols[col][b] += 1
        if once:
            if "exceptions" in once and f.role != "response":
                once.discard("exceptions")
            for col in once:
                cols[col][b] += 1
        if self.summary is not None:
            self.summary.add(f)
        self.diagnosis.frame(f)
        if f.unit is None or f.is_noise:
            return
        write = self.timeline.frame(f, self._capture)
        if write:
            cols["writes"][b] += 1
        fast = self._unit(f, write)
        if fast:
            cols["fast35"][b] += 1
            if fast > 1:
                cols["fast15"][b] += 1
        self.book.frame(f)

    def _unit(self, f, write: bool) -> int:
        """The unit's figures (a unit of its link, with several); 1 for a response under t3.5, 2 under t1.5,
        else 0."""
        fig = self.figures.frame(f)
        key = (f.link, f.unit)
        u = self.units.get(key)
        if u is None:
            u = self.units[key] = UnitAgg(unit_name(fig.unit), fig)
        if f.role == "request":
            u.writes += write
            if f.crc_ok is not False:  # a damaged request's address and function are not what was sent
                self.polls.request(f)
        elif f.role == "response" and f.pair is not None and f.latency_ms is not None:
            self.time_sources[f.time_source] += 1
            char_ns, t15, t35 = self._lines[f.link] if f.link else (self._char_ns, self._t15, self._t35)
            return u.latency(f.t_ns, f.latency_ms, char_ns, f.index, t15, t35)
        return 0

    # ------------------------------------------------------------ the result
    def to_data(self) -> dict:
        """Everything the page draws, JSON-ready; times in seconds from the report's start."""
        units = [self.units[k] for k in sorted(self.units)]
        top = set(sorted((u for u in units if u.fig.latency.n), key=lambda u: -u.fig.latency.n)[:PLOTTED_UNITS])
        timed = [u for u in units if u in top]
        return {
            "findings": [x.to_dict() for x in self.diagnosis.findings()],
            "axis": {"clock": self.clock and self.origin_wall > 0, "origin_wall_s": self.origin_wall / 1e9,
                     "end_s": self.end_ns / 1e9},
            "captures": self.captures,
            "totals": {"frames": sum(c.get("frames", 0) for c in self.captures),
                       "bytes": sum(c.get("bytes", 0) for c in self.captures), "codes": dict(self.codes.most_common())},
            "buckets": self.buckets.to_dict(self.end_ns),
            "units": [u.row() for u in units],
            "latency": {"edges": latency_edges(), "bins": {str(u.unit): u.lat_bins for u in timed},
                        "series": {str(u.unit): series_points(u.lat_series) for u in timed},
                        "units_timed": sum(1 for u in units if u.fig.latency.n)},
            "turnaround": {"edges": turnaround_edges(), "bins": {str(u.unit): u.turn_bins for u in timed},
                           "time_sources": dict(self.time_sources),
                           "capture_time_sources": sorted({c["time_source"] for c in self.captures}),
                           "limits": [list(x) for x in sorted({tuple(x) for c in self.captures for x in c["limits"]})],
                           "t15": self.codes.get(C.T15_VIOLATION.code, 0), "t35": self.codes.get(C.T35_SHORT.code, 0),
                           "below15": sum(u.below15 for u in units), "below35": sum(u.below35 for u in units)},
            "polls": self.polls.to_dict(),
            "registers": self._registers(),
            "timeline": {"events": [{**e, "t": e["t"] / 1e9, "t_end": e["t_end"] / 1e9}
                                    for e in self.timeline.events()],
                         "units": [u.unit for u in units],  # the order of the timeline's rows
                         "counts": dict(self.timeline.counts), "dropped": self.timeline.dropped},
        }

    def _registers(self) -> dict:
        """The registers whose decoded value changed: a table, and plots grouped by unit and engineering unit."""
        changed = sorted((rv for rv in (*self.book.retired, *self.book.values.values()) if rv.history.changes > 0),
                         key=lambda rv: (*_split(rv.unit), rv.table, rv.address))
        rows = []
        for rv in changed:
            h = rv.history
            vals = [v for v in h.v if math.isfinite(v)]
            last = rv.value
            if not isinstance(last, (int, float)) or isinstance(last, float) and not math.isfinite(last):
                last = str(last)[:80]
            rows.append({"unit": str(rv.unit), "table": rv.table, "address": rv.address_text, "name": rv.title,
                         "eng_unit": rv.eng_unit or "", "changes": h.changes, "samples": h.seen,
                         "min": min(vals) if vals else None, "max": max(vals) if vals else None,
                         "last": last, "text": rv.text[:120]})
        groups: dict[tuple, list] = {}
        for rv in sorted(changed, key=lambda rv: -rv.history.changes):
            groups.setdefault((*_split(rv.unit), rv.eng_unit or ""), []).append(rv)
        plots = []
        for (_link, _unit, eng), rvs in sorted(groups.items()):
            if len(plots) >= REGISTER_PLOTS:
                break
            plots.append({"unit": str(rvs[0].unit), "eng_unit": eng, "more": max(0, len(rvs) - SERIES_PER_PLOT),
                          "series": [{"label": rv.title, "address": rv.address_text,
                                      **series_points(rv.history, hold=True)} for rv in rvs[:SERIES_PER_PLOT]]})
        return {"rows": rows, "plots": plots, "groups": len(groups), "registers": len(self.book.values)}
