"""The frame list's time bases: time since the capture's start, wall-clock time, or time from a reference frame.

Textual-free (the model's side, unit-tested without a terminal).  Times are integer nanoseconds on the
capture's clock; the wall clock is the capture's `wall_anchor_ns` (Unix epoch ns at `t0_ns`, 0 when
the capture does not know it: a simulated bus, a byte CSV) plus the time since the start, shown in
the viewer's local time zone.  A time reference is one frame (Wireshark's *REF*): times are shown
from it, before it negative.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone, tzinfo
from decimal import Decimal, InvalidOperation

REL, WALL, REF = "relative", "wall", "reference"
_EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)
_NS = 1_000_000_000
UNIT_NS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": _NS, "min": 60 * _NS, "h": 3600 * _NS}
_DURATION = re.compile(r"([+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))\s*(ns|us|µs|ms|s|min|h)?")
MAX_NS = 2**63 - 1  # what an int64 timestamp holds (about 292 years)


def parse_duration(text: str, bare_unit: str | None = None) -> int:
    """Nanoseconds of `12.5s`, `350ms`, `-20us`, `1.5min` (exact decimals, no float rounding).

    A number without a unit is taken in `bare_unit` (None: a unit is required).  ValueError otherwise.
    """
    m = _DURATION.fullmatch(text.strip())
    unit = m and (m.group(2) or bare_unit)
    if not unit:
        raise ValueError(f"not a time: {text!r} (a number and a unit: 12.5s, 350ms, 20us, 2min)")
    try:
        ns = round(Decimal(m.group(1)) * UNIT_NS[unit])
    except InvalidOperation:  # pragma: no cover - the pattern only lets decimals through
        raise ValueError(f"not a time: {text!r}") from None
    if abs(ns) > MAX_NS:
        raise ValueError(f"time out of range: {text!r}")
    return ns


def delta_text(ns: int) -> str:
    """A short time span for the Δt column (at most 8 characters up to 99,999 s): 0.27ms, 45.90ms, 1.250s."""
    a = abs(ns)
    if a < 999_995_000:
        text, short = f"{ns / 1e6:.2f}ms", f"{ns / 1e6:.1f}ms"
    elif a < 99_999_500_000:
        text, short = f"{ns / 1e9:.3f}s", f"{ns / 1e9:.2f}s"
    else:
        return f"{ns / 1e9:.0f}s"
    return text if len(text) <= 8 else short


def _seconds(ns: int, signed: bool = False) -> str:
    """Seconds with 6 decimals from integer ns (no float: exact for captures of days)."""
    sign = "-" if ns < 0 else "+" if signed else ""
    s, us = divmod((abs(ns) + 500) // 1000, 1_000_000)  # to the nearest microsecond, as the JSONL's t
    return f"{sign}{s}.{us:06d}"


@dataclass
class TimeBase:
    """How the list and the detail show a frame's time (the App's `t` cycles `mode`, `T` sets `ref`)."""

    t0_ns: int = 0  # the capture's start on its own clock
    wall_anchor_ns: int = 0  # wall-clock ns (Unix epoch) at t0_ns; 0: unknown
    mode: str = REL
    ref_row: int | None = None  # the reference frame's row in the store
    ref_t_ns: int = 0
    ref_index: int = 0  # its frame number, for the titles
    tz: tzinfo | None = None  # None: the viewer's local time zone
    version: int = 0  # bumped on every change, so views know to lay out again

    # ---- modes
    @property
    def has_wall(self) -> bool:
        return self.wall_anchor_ns > 0

    def modes(self) -> list[str]:
        """The bases on offer, in the order `t` cycles them."""
        return [REL] + [WALL] * self.has_wall + [REF] * (self.ref_row is not None)

    def cycle(self) -> str | None:
        """The next base (relative -> wall clock -> reference -> relative); None if there is only one."""
        modes = self.modes()
        if len(modes) < 2:
            return None
        self.mode = modes[(modes.index(self.mode) + 1) % len(modes)] if self.mode in modes else REL
        self.version += 1
        return self.mode

    def toggle_reference(self, row: int, t_ns: int, index: int) -> bool:
        """Make this frame the reference and show times from it; on the reference itself, clear it."""
        if self.ref_row == row:
            self.ref_row = None
            if self.mode == REF:
                self.mode = REL
        else:
            self.ref_row, self.ref_t_ns, self.ref_index, self.mode = row, t_ns, index, REF
        self.version += 1
        return self.ref_row is not None

    # ---- wall clock
    def wall_ns(self, t_ns: int) -> int:
        return self.wall_anchor_ns + t_ns - self.t0_ns

    def wall_datetime(self, t_ns: int) -> datetime:
        """The wall-clock time of a capture time, aware, in the viewer's zone (microseconds)."""
        s, rem = divmod(self.wall_ns(t_ns), _NS)
        when = datetime.fromtimestamp(s, self.tz) if self.tz is not None else datetime.fromtimestamp(s).astimezone()
        return when + timedelta(microseconds=rem // 1000)

    def t_of_wall(self, when: datetime) -> int:
        """A capture time (ns) from an aware wall-clock time (exact to the microsecond)."""
        d = when - _EPOCH
        return (d.days * 86_400 + d.seconds) * _NS + d.microseconds * 1000 - self.wall_anchor_ns + self.t0_ns

    def local(self, naive: datetime) -> datetime:
        """A wall-clock time typed without a zone, in the viewer's zone."""
        return naive.replace(tzinfo=self.tz) if self.tz is not None else naive.astimezone()

    # ---- text
    def origin_ns(self) -> int:
        """Where durations typed or shown count from: the reference in that base, else the start."""
        return self.ref_t_ns if self.mode == REF else self.t0_ns

    def text(self, t_ns: int) -> str:
        """A frame's time as the list shows it."""
        if self.mode == WALL:
            when = self.wall_datetime(t_ns)
            return f"{when:%H:%M:%S}.{when.microsecond // 1000:03d}"
        if self.mode == REF:
            return _seconds(t_ns - self.ref_t_ns, signed=True)
        return _seconds(t_ns - self.t0_ns)

    def full_text(self, t_ns: int) -> str:
        """A frame's time in words, as the detail shows it: says which base it is in."""
        if self.mode == WALL:
            return f"{self.wall_text(t_ns)} (wall clock)"
        if self.mode == REF:
            return f"{_seconds(t_ns - self.ref_t_ns, signed=True)}s from the reference #{self.ref_index}"
        return f"{_seconds(t_ns - self.t0_ns)}s since the start"

    def wall_text(self, t_ns: int) -> str:
        when = self.wall_datetime(t_ns)
        return f"{when:%Y-%m-%d %H:%M:%S}.{when.microsecond:06d} {_zone(when)}"

    def all_texts(self, t_ns: int) -> list[str]:
        """The time in every base on offer (the detail's time node)."""
        out = [f"since the start: {_seconds(t_ns - self.t0_ns)}s"]
        out.append(f"wall clock: {self.wall_text(t_ns)}" if self.has_wall else "wall clock: not known for this capture")
        if self.ref_row is not None:
            out.append(f"from the reference #{self.ref_index}: {_seconds(t_ns - self.ref_t_ns, signed=True)}s")
        return out

    def width(self, first_ns: int, last_ns: int) -> int:
        """Characters the list's time column needs for times between first_ns and last_ns."""
        if self.mode == WALL:
            return 12
        return max(len(self.text(first_ns)), len(self.text(last_ns)), len("*REF*"))

    def title(self) -> str:
        """The time column's title: short, names the base."""
        if self.mode == REF:
            return f"from #{self.ref_index}"
        return "wall clock" if self.mode == WALL else "time (s)"

    def describe(self) -> str:
        """The base in words, for the list header."""
        if self.mode == WALL:
            when = self.wall_datetime(self.t0_ns)
            return f"time: wall clock, {when:%Y-%m-%d} {_zone(when)}"
        if self.mode == REF:
            return f"time: from the reference #{self.ref_index}"
        return "time: since the capture's start"


def _zone(when: datetime) -> str:
    off = when.utcoffset() or timedelta(0)
    sign = "-" if off < timedelta(0) else "+"
    minutes = abs(int(off.total_seconds())) // 60
    return f"UTC{sign}{minutes // 60:02d}:{minutes % 60:02d}"
