"""The TUI's model: every frame seen, compactly, with columns for filters, per-unit stats, registers.

Free of Textual (toolong keeps its App thin and its model plain): the store is
driven by `add(frames)` from the UI thread (the sink buffers frames from the
capture thread, see `sink.py`) and unit-tested without a terminal.

Rows are positions in arrival order; `Frame.index` / `Frame.pair` are the
pipeline's numbers, mapped to rows with `row_of`.  What the list, filters and
navigation need per row is in `array` columns (time, unit, function, role,
flags, pair, latency, registers touched, model, and the index map: 41 bytes a row);
the frames themselves are packed in compressed
blocks (framepack.py) and rebuilt for the rows on screen, so a million-frame
replay costs tens of MB, not gigabytes.  The view is an `array` of rows that
pass the filter, appended to as frames arrive.  The filter is a
`sniffer.filterlang.Query`: the store is its `cols` (the columns, the search
text, `peek` for the frames), so it is answered from the columns first.
"""

from __future__ import annotations

import bisect
import time
from array import array
from dataclasses import dataclass

from types import SimpleNamespace

from sniffer.diagnose import Diagnosis
from sniffer.filterlang import Query, matches_text, register_cell, registers_of
from sniffer.line import LineSettings, SettingsError
from sniffer.frame import Frame
from sniffer.analysis.flags import (  # the store's flag column (re-exported for the views)
    F_CRC, F_ERROR, F_EXC, F_FAULT, F_NOISE, F_PROBLEM, F_TIMEOUT, F_WARN, frame_flags,
)
from sniffer.tui.filters import filter_query
from sniffer.tui.framepack import BLOCK, FRAME_CACHE, FrameBlocks, FrameSeq, RowIndex
from sniffer.analysis.history import CAP
from sniffer.analysis.register_book import RegisterBook, RegisterValue
from sniffer.formats.records import frame_from_record
from sniffer.analysis.unitfigures import UnitBook, UnitFigures, counted
from sniffer.tui.timebase import TimeBase
from sniffer.tui.transactions import Transactions

ROLES = ("request", "response", "unknown", "noise")
ROLE_CODE = {r: i for i, r in enumerate(ROLES)}
_NO_ROLE = 255  # a role outside ROLES (none today)

__all__ = ["F_CRC", "F_ERROR", "F_EXC", "F_FAULT", "F_NOISE", "F_PROBLEM", "F_TIMEOUT", "F_WARN", "Filter",
           "FrameStore", "RegisterValue", "RowIndex", "UnitFigures", "frame_flags", "frame_from_record"]


def _code(codes: dict, names: list, name) -> int:
    """A name's code in a column of names (a model, a link): a new name gets the next (at most 255)."""
    code = codes.get(name)
    if code is None:
        code = codes[name] = min(len(names), 255)
        names.append(name)
    return code


@dataclass
class Filter:
    units: frozenset[int] | None = None
    links: frozenset[str] | None = None  # link names (a capture of several links), lower case
    functions: frozenset[int] | None = None
    roles: frozenset[str] | None = None
    errors_only: bool = False
    text: str = ""  # the rest of the filter, in the filter language (sniffer.filterlang): words, reg:, values ...

    @property
    def active(self) -> bool:
        return bool(self.units is not None or self.links is not None or self.functions is not None
                    or self.roles is not None
                    or self.errors_only or self.text)

    def describe(self) -> str:
        parts = []
        if self.links is not None:
            parts.append("link " + ",".join(sorted(self.links)))
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


class FrameStore:
    """All frames of a capture plus what the views need to find them quickly."""

    def __init__(self, t0_ns: int = 0, *, block: int = BLOCK, frame_cache: int = FRAME_CACHE,
                 ids: dict | None = None, history_cap: int = CAP) -> None:
        self.time = TimeBase(t0_ns)  # how times are shown: since the start, wall clock, from a reference
        self.blocks = FrameBlocks(block, frame_cache)
        self.frames = FrameSeq(self.blocks)
        # columns, one entry per row
        self.t_ns = array("q")
        self.unit = array("h")  # -1: none
        self.function = array("h")  # -1: none
        self.role = array("B")  # ROLE_CODE
        self.flags = array("B")
        self.pair = array("q")  # the pair's Frame.index, -1: none
        self.lat_us = array("i")  # a response's latency in microseconds, -1: none
        self.reg = array("i")  # the registers a frame touches (filterlang.register_cell), with:
        self.nreg = array("H")
        self.model = array("B")  # index into model_names
        self.link = array("B")  # index into link_names (a capture of several links; one line: all 0, "")
        self.link_names: list[str] = []
        self._link_code: dict[str, int] = {}
        self.model_names: list[str | None] = []
        self._model_code: dict[str | None, int] = {}
        self.role_code = ROLE_CODE
        self.ids = ids or {}  # parameter id -> registers, for reg:12-00 (filterlang.register_ids of a registry)
        self._query = Query(None)
        self.row_of = RowIndex()
        self.filter = Filter()
        self.view = array("q")  # rows passing the filter (up to the pause point)
        self.problems = array("q")  # rows with any problem flag (unfiltered)
        self.units = UnitBook()  # per unit (frame.unit_key: a unit of its link, with several links) its figures
        self.book = RegisterBook(history_cap)  # the frames' `writes` applied: the decoders' register shadow
        self.registers = self.book.values  # (unit, table, address) -> RegisterValue
        self.transactions = Transactions()  # request + response as one entry, per-unit latency
        self.diagnosis = Diagnosis()  # sniffer diagnose's engine over the frames taken in (the Verdicts tab)
        self._diagnosis_of = None  # the CaptureInfo it was started with
        self.booked = 0  # rows the register book and the diagnosis have taken (add(books=False): catch_up)
        self.bookmarks: set[int] = set()
        self.paused_at: int | None = None  # row count when the view was paused
        self.bytes_total = 0
        self.noise_bytes = 0
        self.generation = 0  # bumped on every change the views must redraw for

    @property
    def several_links(self) -> bool:
        """Frames of more than one link came in: the lists show a link column."""
        return len(self.link_names) > 1

    @property
    def link_width(self) -> int:
        """How wide the lists' link column is: the longest link name, 0 (no column) for one line."""
        return max(map(len, self.link_names)) if self.several_links else 0

    @property
    def t0_ns(self) -> int:
        return self.time.t0_ns

    @t0_ns.setter
    def t0_ns(self, t0_ns: int) -> None:
        self.time.t0_ns = t0_ns

    # ------------------------------------------------------------- intake
    def __len__(self) -> int:
        return len(self.flags)

    def frame(self, row: int) -> Frame:
        """The frame at a row (rebuilt from its block, or from the cache)."""
        return self.blocks.get(row)

    @property
    def last_t_ns(self) -> int:
        return self.t_ns[-1] if self.t_ns else 0

    def add(self, frames, books: bool = True) -> int:
        """Append settled frames (UI thread); returns how many were added.

        `books`: the register book and the diagnosis take them now (when they are not behind).  Without, the
        frames reach the list and the filters only; the books take them later, in order, from the packed
        blocks (`catch_up`): a replay loading fills the list first (the book and the diagnosis were 80 % of
        a frame's cost here, and only the Registers, Plot and Verdicts tabs show them)."""
        now = books and self.booked == len(self)
        frames = frames if type(frames) is list else list(frames)
        n = len(frames)
        if n:
            self._add_batch(frames, now)
            self.generation += 1
            if now:
                self.booked = len(self)
        return n

    @property
    def books_behind(self) -> int:
        """Rows the register book and the diagnosis have not taken yet."""
        return len(self) - self.booked

    def catch_up(self, budget_s: float | None = None, clock=time.perf_counter) -> int:
        """The register book and the diagnosis take the rows they are behind, in arrival order, for about
        `budget_s` (None: all); returns how many they took."""
        start, end = self.booked, len(self)
        get, book, diagnose = self.blocks.peek, self.book, self.diagnosis.frame
        t0 = clock()
        r = start
        while r < end:
            f = get(r)
            if counted(f):  # as in _add_batch: a frame its unit's figures count
                book.frame(f)
            diagnose(f)
            r += 1
            if budget_s is not None and not (r - start) & 63 and clock() - t0 >= budget_s:
                break
        self.booked = r
        return r - start

    def add_records(self, records) -> int:
        """Append JSONL / MCAP `/frames` records (sniffer.formats.records.frame_record) as frames."""
        return self.add(frame_from_record(r, self.t0_ns) for r in records)

    def _add_batch(self, frames: list, books: bool) -> None:
        """Frames in as one block of rows: each column extended once from a list (a frame's dozen
        `array.append` calls were a fifth of its cost while the books waited), then what goes frame by frame
        in order (the transactions, the view's filter, the unit and register books, the diagnosis)."""
        row0 = len(self.flags)
        fls = [frame_flags(f) for f in frames]
        regs = [registers_of(f) for f in frames]
        cells = [register_cell(r) for r in regs]
        blocks = self.blocks
        for f in frames:
            blocks.append(f)
        self.flags.extend(fls)
        self.t_ns.extend([f.t_ns for f in frames])
        self.unit.extend([-1 if f.unit is None else f.unit for f in frames])
        self.function.extend([-1 if f.function is None else f.function for f in frames])
        role = ROLE_CODE.get
        self.role.extend([role(f.role, _NO_ROLE) for f in frames])
        self.pair.extend([-1 if f.pair is None else f.pair for f in frames])
        self.lat_us.extend([-1 if (lat := f.latency_ms) is None else min(round(lat * 1000), 0x7FFFFFFF)
                            for f in frames])
        self.reg.extend([c[0] for c in cells])
        self.nreg.extend([c[1] for c in cells])
        self.model.extend([_code(self._model_code, self.model_names, f.model) for f in frames])
        self.link.extend([_code(self._link_code, self.link_names, f.link) for f in frames])
        ix = self.row_of
        idx = [f.index for f in frames]
        if (ix.rows is None and not ix.extra and (not ix.keys or idx[0] > ix.keys[-1])
                and all(a < b for a, b in zip(idx, idx[1:]))):
            ix.keys.extend(idx)  # in order, as the pipeline numbers them: RowIndex.add's common case
        else:
            for k, index in enumerate(idx):
                ix.add(index, row0 + k)
        self.bytes_total += sum([len(f.raw) for f in frames])
        self.problems.extend([row0 + k for k, fl in enumerate(fls) if fl & F_PROBLEM])
        query = None if self.paused_at is not None else self._query
        view, tx, units, book, diagnose = self.view, self.transactions, self.units, self.book, self.diagnosis.frame
        for k, f in enumerate(frames):
            row, fl = row0 + k, fls[k]
            if fl & F_NOISE:
                self.noise_bytes += len(f.raw)
            tx.add(row, f, fl)
            if query is not None and (not query or query.matches(f, self, fl, regs[k])):
                view.append(row)
            if units.frame(f) is not None and books:
                book.frame(f)
            if books:
                diagnose(f)

    def start_diagnosis(self, info, registry=None) -> None:
        """The diagnosis engine's settings: each link's line as the capture's metadata says it, the models of the
        decoders' registry (None: a viewer attached to a capture has none: one is made from the models its
        metadata names).  Once per capture (the App asks until the first frame comes)."""
        if info is self._diagnosis_of:
            return
        self._diagnosis_of = info
        resolved = {}
        for name, d in [(str(x.get("name", "")), x) for x in info.links] or [("", info.to_dict())]:
            try:
                line = LineSettings(int(d.get("baud") or 9600), str(d.get("parity") or "N"),
                                    int(d.get("stopbits") or 1), int(d.get("databits") or 8))
            except (SettingsError, TypeError, ValueError):
                continue
            resolved[name] = SimpleNamespace(line=line)
        if registry is None:  # a viewer of a capture running elsewhere: the models its metadata names
            try:
                from decoders.registry import default_registry

                registry = default_registry(dict(info.devices))
            except Exception:  # noqa: BLE001 - a model this side does not know: diagnose without the maps
                registry = None
        self.diagnosis.start(info, resolved, {name: registry for name in resolved} if registry is not None else {})

    # ------------------------------------------------------------- filters
    def set_filter(self, flt: Filter) -> None:
        """Filter the view (FilterError, a ValueError, if its text does not parse: the filter stays)."""
        self._query = filter_query(flt)
        self.filter = flt
        self._rebuild()

    def update_filter(self, **kw) -> Filter:
        d = dict(self.filter.__dict__)
        d.update(kw)
        self.set_filter(Filter(**d))
        return self.filter

    def _rebuild(self) -> None:
        end = len(self) if self.paused_at is None else self.paused_at
        self.view = array("q", self._query.rows(self, end)) if self._query else array("q", range(end))
        self.generation += 1

    def peek(self, row: int) -> Frame:
        """A row's frame for a filter's look (not kept in the cache of rows on screen)."""
        return self.blocks.peek(row)

    def resolve_id(self, word: str) -> tuple:
        return self.ids.get(word, ())

    def text_rows(self, rows, needle: str) -> array:
        """The rows among `rows` whose frame's search text holds `needle` (lower case), ascending."""
        return self._text_rows(rows if isinstance(rows, range) else sorted(rows), needle)

    def _text_rows(self, rows, needle: str) -> array:
        """The rows among `rows` (ascending) whose frame matches the free text."""
        blocks, size = self.blocks, self.blocks.block
        sealed = blocks.sealed_rows
        nb = needle.encode("utf-8", "surrogatepass")
        role = ROLE_CODE.get(needle)
        roles = self.role
        out = array("q")
        if isinstance(rows, range) and role is None:  # every row: block by block
            for b in range(min(sealed, rows.stop) // size):
                out.extend(b * size + i for i in blocks.search(b, nb))
            start = min(sealed, rows.stop) // size * size
            out.extend(r for r in range(start, rows.stop) if matches_text(blocks.get(r), needle))
            return out
        cur, hits = -1, frozenset()
        for r in rows:
            if role is not None and roles[r] == role:
                out.append(r)
            elif r >= sealed:
                if matches_text(blocks.get(r), needle):
                    out.append(r)
            else:
                b = r // size
                if b != cur:
                    cur, hits = b, frozenset(blocks.search(b, nb))
                if r - b * size in hits:
                    out.append(r)
        return out

    # ------------------------------------------------------------- pause
    @property
    def paused(self) -> bool:
        return self.paused_at is not None

    def pause(self, on: bool | None = None) -> bool:
        """Freeze the view (capture and stats go on); resuming catches up."""
        on = not self.paused if on is None else on
        if on and self.paused_at is None:
            self.paused_at = len(self)
        elif not on and self.paused_at is not None:
            self.paused_at = None
            self._rebuild()
        self.generation += 1
        return self.paused

    # ------------------------------------------------------------- lookup
    def frame_at(self, pos: int) -> Frame:
        """The frame at position `pos` of the view."""
        return self.blocks.get(self.view[pos])

    def pos_of_row(self, row: int) -> int | None:
        """Position of a row in the view, or None if filtered out."""
        i = bisect.bisect_left(self.view, row)
        return i if i < len(self.view) and self.view[i] == row else None

    def nearest_pos(self, row: int) -> int:
        return min(bisect.bisect_left(self.view, row), max(len(self.view) - 1, 0))

    def pair_row(self, row: int) -> int | None:
        p = self.pair[row]
        return None if p < 0 else self.row_of.get(p)

    def next_problem(self, row: int, forward: bool = True) -> int | None:
        """The next (previous) row with a problem, after (before) `row`, within the view's range."""
        end = len(self) if self.paused_at is None else self.paused_at
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

    def unit_rows(self) -> list[UnitFigures]:
        return self.units.rows()

    def register_rows(self, unit: int | None = None) -> list[RegisterValue]:
        """Latest value per (unit, table, address): the register shadow with names and units."""
        return self.book.rows(unit)
