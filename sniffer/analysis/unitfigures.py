"""Per-unit figures, each with one definition: what every view shows of a unit.

The TUI's Units tab and latency histogram, the HTML report, the status file (`sniffer status`),
`sniffer diff`, the MQTT health topics all count through `UnitBook`; the dataset's `units` query
preset (`sniffer.dataset.query.UNITS_SQL`) says the same in SQL.  Textual-free and sans-I/O: O(1) a frame, memory flat
whatever the capture's length.

    book = UnitBook()
    for f in frames: book.frame(f)
    book.rows()          # UnitFigures per unit, in unit order
    book.to_dict()       # {"1": {"requests": ..., "lat_median": ...}, ...}

Which frames count: every frame that names a unit and is not noise, under `frame.unit_key` (a unit
of its link, with several links), whatever its CRC: the line carried it and the pairer gave it a
role.  A CRC-bad frame counts in `crc_errors` too; its unit byte may be the damage, so a unit seen
in CRC-bad frames only is a `ghost`.  What an annotation counts as is its code's category
(`sniffer.codes`, `Code.category`): no view keeps its own list of codes.  docs/figures.md says the
same for a reader.
"""

from __future__ import annotations

import bisect
from collections import deque
from fractions import Fraction

from decoders.registry import code_book
from sniffer import codes
from sniffer.frame import REQUEST, RESPONSE, Frame, unit_key

RATE_WINDOW_NS = 10_000_000_000  # `poll_rate`: requests per second over the last 10 s of capture time
QUANTILES = (("lat_median", 0.5), ("lat_p95", 0.95), ("lat_p99", 0.99))

# the categories a unit's figures count, as bits (one dict lookup per annotation)
_TIMEOUT, _END, _LATE, _RETRY, _EXC, _FAULT, _ALARM = (1 << i for i in range(7))
_BIT_OF_CATEGORY = {codes.TIMEOUT_CAT: _TIMEOUT, codes.END_OF_CAPTURE_CAT: _END, codes.LATE_CAT: _LATE,
                    codes.RETRY_CAT: _RETRY, codes.EXCEPTION_CAT: _EXC, codes.FAULT_CAT: _FAULT,
                    codes.ALARM_CAT: _ALARM}
_BIT = {code: _BIT_OF_CATEGORY[cat] for code, cat in code_book().categories.items() if cat in _BIT_OF_CATEGORY}


class Latencies:
    """Response latencies in flat memory: how many, the least, the most, and quantiles by the nearest rank.

    The q-quantile of n latencies is the one at rank ceil(q * n) (1-based) of them in ascending
    order: the median of an even count is the lower middle one (DuckDB's `quantile_disc` is the
    same).  A latency is counted per microsecond (Frame.latency_ms is to the microsecond), so the
    quantiles are exact while at most EXACT_VALUES distinct latencies came; beyond, a latency
    of 1.024 ms or more is counted in a bucket 1/512 of an octave wide (shorter ones stay exact)
    and a quantile is its bucket's middle: within 1/1024 (0.1 %) of the exact figure (`exact`
    says which).  The least and the most are always exact.  At most about 10,000 buckets
    (1 ms .. 100 s), however many latencies.
    """

    EXACT_VALUES = 4096
    _SUB = 10  # bits kept of a latency in microseconds, past EXACT_VALUES distinct ones

    __slots__ = ("n", "_counts", "exact", "_min", "_max", "_sorted")

    def __init__(self) -> None:
        self.n = 0
        self._counts: dict[int, int] = {}  # microseconds (or a bucket's middle) -> how many
        self.exact = True
        self._min = self._max = 0
        self._sorted: tuple | None = None  # (keys ascending, cumulative counts), until the next add

    def add(self, ms: float) -> None:
        us = round(ms * 1000)
        if self.n == 0 or us < self._min:
            self._min = us
        if self.n == 0 or us > self._max:
            self._max = us
        self.n += 1
        self._sorted = None
        c = self._counts
        key = us if self.exact else _bucket(us)
        c[key] = c.get(key, 0) + 1
        if self.exact and len(c) > self.EXACT_VALUES:
            self.exact = False
            merged: dict[int, int] = {}
            for k, n in c.items():
                b = _bucket(k)
                merged[b] = merged.get(b, 0) + n
            self._counts = merged

    @property
    def min(self) -> float | None:
        return self._min / 1000 if self.n else None

    @property
    def max(self) -> float | None:
        return self._max / 1000 if self.n else None

    def _cumulative(self) -> tuple:
        s = self._sorted
        if s is None:
            keys = sorted(self._counts)
            cum, seen, c = [], 0, self._counts
            for k in keys:
                seen += c[k]
                cum.append(seen)
            s = self._sorted = (keys, cum)
        return s

    def quantile(self, q: float) -> float | None:
        """The q-quantile in ms by the nearest rank (see the class doc), or None without a latency."""
        if not self.n:
            return None
        rank = max(1, -(-Fraction(str(q)) * self.n // 1))  # ceil(q * n), exactly
        if rank >= self.n:
            return self._max / 1000
        keys, cum = self._cumulative()
        k = keys[bisect.bisect_left(cum, rank)]  # the first value with `rank` values at or below it
        return min(max(k, self._min), self._max) / 1000

    @property
    def median(self) -> float | None:
        return self.quantile(0.5)

    def bins(self, edges) -> list[int]:
        """How many latencies fall in each (previous edge, edge] in ms, then one more past the last edge."""
        out = [0] * (len(edges) + 1)
        for k, n in self._counts.items():
            out[bisect.bisect_left(edges, k / 1000)] += n
        return out

    def figures(self) -> dict:
        """lat_n, lat_min, lat_median, lat_p95, lat_p99, lat_max (ms; None without a latency), lat_exact."""
        d = {"lat_n": self.n, "lat_min": self.min}
        for name, q in QUANTILES:
            d[name] = self.quantile(q)
        d["lat_max"] = self.max
        d["lat_exact"] = self.exact
        return d


def _bucket(us: int) -> int:
    """The middle of the bucket a latency in microseconds falls in past EXACT_VALUES (see Latencies)."""
    a = -us if us < 0 else us
    e = a.bit_length() - Latencies._SUB
    if e <= 0:
        return us
    mid = ((a >> e) << e) + (1 << (e - 1))
    return -mid if us < 0 else mid


class UnitFigures:
    """One unit's figures.  Every count is of frames that name the unit (see the module doc).

    requests           frames the pairer took as requests to the unit: retries and broadcasts
                       (unit 0) included, CRC-bad ones too.
    responses          frames the pairer took as responses from the unit: paired, late, orphan,
                       exception and CRC-bad ones alike.
    crc_errors         frames naming the unit, either role, whose CRC (LRC) does not match.
    exceptions         responses that are exception responses (Modbus function | 0x80, PD 81H/83H).
    timeouts           requests that got no response: the pairer settled them unanswered because the
                       next request came or the unit's response timeout passed (pair.no_response,
                       pair.timeout; once a request).  Not a timeout: a broadcast (no answer is
                       expected), a request the capture ended on (`unanswered_at_end`), a late
                       response (answered: `late`).
    retries            requests repeating, byte for byte, the unanswered request just before them.
    faults             frames in which the drive reports a fault (trip).
    alarms             frames in which the drive reports an alarm (warning).
    late               responses that came after the unit's response timeout: answered, so not
                       timeouts, and their latency counts.
    unanswered_at_end  requests still waiting for their response when the capture ended (the
                       answer may simply not have been captured).
    unmeasured         responses paired with their request but without a latency (read with their
                       request in one USB read; typed-in frames).
    latency            `Latencies` of every response paired with its request that has a latency:
                       ms from the end of the request's last byte to the start of the response's
                       first (`Frame.latency_ms`); exception, late and CRC-bad responses included.
    good               CRC-good frames naming the unit (none: `ghost`, perhaps a damaged address).
    """

    __slots__ = ("unit", "model", "requests", "responses", "crc_errors", "exceptions", "timeouts", "retries",
                 "faults", "alarms", "late", "unanswered_at_end", "unmeasured", "good", "latency", "first_ns",
                 "last_ns", "first_request_ns", "last_request_ns", "recent_requests")

    COUNTS = ("requests", "responses", "crc_errors", "exceptions", "timeouts", "retries", "faults", "alarms", "late",
              "unanswered_at_end", "unmeasured")

    def __init__(self, unit) -> None:
        self.unit = unit  # frame.unit_key: the number, or a LinkUnit with several links; None: every unit
        self.model: str | None = None
        self.requests = self.responses = self.crc_errors = self.exceptions = self.timeouts = self.retries = 0
        self.faults = self.alarms = self.late = self.unanswered_at_end = self.unmeasured = self.good = 0
        self.latency = Latencies()
        self.first_ns: int | None = None
        self.last_ns = 0
        self.first_request_ns: int | None = None
        self.last_request_ns = 0
        self.recent_requests: deque = deque()  # t_ns of the requests in the last RATE_WINDOW_NS

    @property
    def ghost(self) -> bool:
        """Only CRC-bad frames named the unit: likely a damaged address byte, not a device."""
        return not self.good

    # the names the views used before (the TUI's Units tab, MQTT health)
    @property
    def last_seen_ns(self) -> int:
        return self.last_ns

    @property
    def lat_min(self) -> float | None:
        return self.latency.min

    @property
    def lat_median(self) -> float | None:
        return self.latency.median

    @property
    def lat_max(self) -> float | None:
        return self.latency.max

    @property
    def poll_rate(self) -> float:
        """Requests per second over the last RATE_WINDOW_NS of capture time (what the master does now)."""
        r = self.recent_requests
        if len(r) < 2:
            return 0.0
        span = (r[-1] - r[0]) / 1e9
        return (len(r) - 1) / span if span > 0 else 0.0

    @property
    def polls_per_s(self) -> float | None:
        """Requests per second from the unit's first request to its last (the mean over the capture)."""
        if self.requests < 2 or self.first_request_ns is None or self.last_request_ns <= self.first_request_ns:
            return None
        return (self.requests - 1) / ((self.last_request_ns - self.first_request_ns) / 1e9)

    def count(self, f: Frame) -> float | None:
        """Count frame `f`, which names this unit (see the class doc for what each figure takes); the latency
        it added, if any."""
        m = f.model
        if m and (m != "generic" or self.model is None):
            self.model = m
        t = f.t_ns
        if self.first_ns is None:
            self.first_ns = t
        self.last_ns = t
        seen = 0
        added = None
        for a in f.annotations:
            seen |= _BIT.get(a.code, 0)
        role = f.role
        if role == REQUEST:
            self.requests += 1
            if self.first_request_ns is None:
                self.first_request_ns = t
            self.last_request_ns = t
            r = self.recent_requests
            r.append(t)
            while t - r[0] > RATE_WINDOW_NS:
                r.popleft()
            if seen:
                if seen & _TIMEOUT:
                    self.timeouts += 1
                if seen & _END:
                    self.unanswered_at_end += 1
                if seen & _RETRY:
                    self.retries += 1
        elif role == RESPONSE:
            self.responses += 1
            if seen & _LATE:
                self.late += 1
            if seen & _EXC:
                self.exceptions += 1
            if f.pair is not None:
                lat = f.latency_ms
                if lat is None:
                    self.unmeasured += 1
                else:
                    self.latency.add(lat)
                    added = lat
        if seen & _FAULT:
            self.faults += 1
        if seen & _ALARM:
            self.alarms += 1
        ok = f.crc_ok
        if ok is False:
            self.crc_errors += 1
        elif ok:
            self.good += 1
        return added

    def counts(self) -> dict:
        return {name: getattr(self, name) for name in self.COUNTS}

    def to_dict(self) -> dict:
        """The figures, JSON-ready: unit (its name), model, ghost, the counts, the latency's figures (ms)."""
        return {"unit": unit_name(self.unit), "model": self.model, "ghost": self.ghost, **self.counts(),
                **self.latency.figures()}


def unit_name(unit) -> str:
    """A unit as every view names it: "3", or "LINK:3" for a unit of one link of several."""
    return "all" if unit is None else str(unit)


def counted(f: Frame) -> bool:
    """Does a frame count for its unit (UnitBook.frame)?  One that names no unit, or noise, does not."""
    return f.unit is not None and f.protocol != "noise"


class UnitBook:
    """Every unit's figures, and the latencies of all of them together (see the module doc)."""

    def __init__(self) -> None:
        self.units: dict = {}  # frame.unit_key -> UnitFigures
        self.latency = Latencies()  # every unit's, as one stream

    def frame(self, f: Frame) -> UnitFigures | None:
        """Count a frame; its unit's figures (None for a frame that names no unit, or noise)."""
        if not counted(f):
            return None
        key = unit_key(f)
        u = self.units.get(key)
        if u is None:
            u = self.units[key] = UnitFigures(key)
        lat = u.count(f)
        if lat is not None:
            self.latency.add(lat)
        return u

    def __contains__(self, key) -> bool:
        return key in self.units

    def __getitem__(self, key) -> UnitFigures:
        return self.units[key]

    def get(self, key, default=None):
        return self.units.get(key, default)

    def __len__(self) -> int:
        return len(self.units)

    def __iter__(self):
        return iter(self.units)

    def values(self):
        return self.units.values()

    def items(self):
        return self.units.items()

    def rows(self) -> list[UnitFigures]:
        """Every unit's figures, in unit order (with several links: by link, then unit)."""
        return [self.units[k] for k in sorted(self.units)]

    def total(self) -> UnitFigures:
        """Every unit's counts added up, and every unit's latencies as one stream (unit None: "all")."""
        t = UnitFigures(None)
        for u in self.units.values():
            for name in UnitFigures.COUNTS:
                setattr(t, name, getattr(t, name) + getattr(u, name))
            t.good += u.good
        t.latency = self.latency
        return t

    def to_dict(self) -> dict:
        """{unit name: UnitFigures.to_dict()} in unit order."""
        return {unit_name(u.unit): u.to_dict() for u in self.rows()}


__all__ = ["Latencies", "UnitBook", "UnitFigures", "unit_name"]
