"""Go to a frame number or a time (the `g` bar): what was typed, and the row it lands on.

Textual-free.  `1234` or `#1234` is a frame number; `12.5s`, `350ms`, `12.5` (a decimal point: seconds)
a time since the capture's start, or from the time reference when times are shown from it;
`19:22:01.250` (or `2024-05-01 19:22:01.250`) a wall-clock time.  A time lands on the first frame at
or after it; a frame the filter hides (or a paused view leaves out) lands on the nearest shown one,
and the note says so.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass
from datetime import datetime, time, timedelta

from sniffer.tui.timebase import TimeBase, parse_duration

EXAMPLES = "1234 or #1234 (a frame), 12.5s or 350ms (a time), 19:22:01.250 (wall clock)"
_FRAME = re.compile(r"#?([0-9]+)")
_CLOCK = re.compile(r"(?:([0-9]{4}-[0-9]{2}-[0-9]{2})[ T])?([0-9]{1,2}):([0-9]{2})(?::([0-9]{2})(?:\.([0-9]{1,9}))?)?")
_DAY = timedelta(days=1)


@dataclass(frozen=True)
class Target:
    """A frame number, or a capture time (ns on the capture's clock) with how it was typed."""

    index: int | None = None
    t_ns: int | None = None
    text: str = ""


def parse_goto(text: str, tb: TimeBase, last_t_ns: int | None = None) -> Target:
    """What `text` asks for (ValueError with a sentence if nothing); `last_t_ns` places a bare time of day."""
    s = text.strip()
    m = _FRAME.fullmatch(s)
    if m:
        return Target(index=int(m.group(1)), text=s)
    m = _CLOCK.fullmatch(s)
    if m:
        return Target(t_ns=_clock_ns(m, tb, last_t_ns), text=s)
    try:
        return Target(t_ns=tb.origin_ns() + parse_duration(s, bare_unit="s" if "." in s else None), text=s)
    except ValueError:
        raise ValueError(f"go to: {s!r} is not a frame number or a time; try {EXAMPLES}") from None


def _clock_ns(m: re.Match, tb: TimeBase, last_t_ns: int | None) -> int:
    if not tb.has_wall:
        raise ValueError("go to: this capture has no wall-clock start; give a time since the start (12.5s) "
                         "or a frame number")
    day, hh, mm, ss, frac = m.groups()
    try:
        clock = time(int(hh), int(mm), int(ss or 0))
        start = tb.wall_datetime(tb.t0_ns)
        when = tb.local(datetime.combine(datetime.fromisoformat(day).date() if day else start.date(), clock))
    except ValueError as e:
        raise ValueError(f"go to: {m.group(0)!r} is not a wall-clock time ({e})") from None
    if not day and when < start and last_t_ns is not None and tb.wall_datetime(last_t_ns) >= when + _DAY:
        when += _DAY  # a time of day before the start, in a capture that ran past midnight: the next day
    return tb.t_of_wall(when) + int((frac or "0").ljust(9, "0"))


def nearest_shown(view, row: int) -> int | None:
    """The row of `view` (ascending rows) closest to `row`, the later one on a tie; None if view is empty."""
    i = bisect.bisect_left(view, row)
    after = view[i] if i < len(view) else None
    before = view[i - 1] if i > 0 else None
    if after is None or before is not None and row - before < after - row:
        return before
    return after


def resolve(store, target: Target) -> tuple[int, str | None]:
    """(row to select, a note when it is not the frame asked for); ValueError if there is none."""
    tb = store.time
    n = len(store)
    if not n:
        raise ValueError("go to: no frames yet")
    if target.index is not None:
        row = store.row_of.get(target.index)
        if row is None:
            first, last = store.frame(0).index, store.frame(n - 1).index
            raise ValueError(f"go to: no frame #{target.index} here (frames #{first}..#{last})")
        what = f"#{target.index}"
    else:
        row = bisect.bisect_left(store.t_ns, target.t_ns)
        if row == n:
            raise ValueError(f"go to: no frame at or after {tb.full_text(target.t_ns)} "
                             f"(the last is at {tb.full_text(store.t_ns[n - 1])})")
        what = f"the first frame at or after {target.text} (#{store.frame(row).index})"
    if store.pos_of_row(row) is not None:
        return row, None
    shown = nearest_shown(store.view, row)
    if shown is None:
        raise ValueError(f"go to: {what} is hidden and nothing is shown (c clears the filters)")
    why = "the paused view ends before it" if store.paused_at is not None and row >= store.paused_at \
        else "hidden by the filter"
    return shown, f"{what} is {why}: at #{store.frame(shown).index}, the nearest shown frame"
