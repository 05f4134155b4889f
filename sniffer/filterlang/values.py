"""The values a filter names: numbers, durations, register notations, and ranges of them.

Each parser takes one piece of text and returns its value, or raises `BadValue`
with the offset (within that text) of what it could not read, so the parser can
point at the column.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from sniffer.protocols import TABLES


class BadValue(ValueError):
    """A value that does not read; `offset` is where in its text."""

    def __init__(self, msg: str, offset: int = 0) -> None:
        super().__init__(msg)
        self.offset = offset


_DEC = re.compile(r"[+-]?\d+\Z")
_HEX_H = re.compile(r"([0-9a-f]+)h\Z", re.I)  # the manuals' 2520H
_HEX_0X = re.compile(r"0x([0-9a-f]+)\Z", re.I)
_NUM = re.compile(r"([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?)\s*(\S*)\Z", re.I)
_TABLE_REG = re.compile(r"(%s)\[([^\]]*)\]\Z" % "|".join(TABLES), re.I)


def parse_int(s: str) -> int | None:
    """An integer as a user types one: 300, 0x12C, 012CH (hex with the manuals' H); None if it is none."""
    if _DEC.match(s):
        return int(s)
    m = _HEX_0X.match(s) or _HEX_H.match(s)
    return int(m.group(1), 16) if m else None


def parse_number(s: str) -> tuple[float | int, str] | None:
    """(number, unit text after it) for 50, 50.5, -3, 1e3, 0x10, 2520H, 50Hz, 20ms; None if no number leads."""
    n = parse_int(s)
    if n is not None:
        return n, ""
    m = _NUM.match(s)
    if not m:
        return None
    text = m.group(1)
    v = float(text)
    if not math.isfinite(v):
        return None
    return (int(text) if _DEC.match(text) else v), m.group(2)


_TIME_UNITS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": 1_000_000_000, "sec": 1_000_000_000,
               "m": 60_000_000_000, "min": 60_000_000_000, "h": 3_600_000_000_000, "d": 86_400_000_000_000,
               "w": 604_800_000_000_000}
TIME_UNITS_TEXT = "ns, us, ms, s, min, h, d"


def parse_duration(s: str, default: str | None) -> float:
    """Nanoseconds of 20ms, 1.5s, 300us, 2min, 1h, 7d: the one grammar of a time, in a filter and in every
    flag that takes one (`--duration`, `--pre`, `--rotate` ...).  A bare number is in `default` units
    ("s" or "ms"; None: a unit is required).  Decimal only: 2h is two hours, not the manuals' hex 2H."""
    m = _NUM.match(s)
    got = None if m is None or not math.isfinite(float(m.group(1))) else (float(m.group(1)), m.group(2))
    if got is None or (got[1] and got[1].lower() not in _TIME_UNITS):
        if got is None:
            raise BadValue(f"not a time: {s!r} (e.g. 20ms, 1.5s, 300us)")
        raise BadValue(f"unknown time unit {got[1]!r} ({TIME_UNITS_TEXT})", len(s) - len(got[1]))
    v, unit = got
    if not unit and default is None:
        raise BadValue(f"a time needs its unit: {s!r} ({TIME_UNITS_TEXT}, e.g. {s.strip()}s)")
    return v * _TIME_UNITS[unit.lower() or default]


def show_duration(ns: float) -> str:
    """A duration as the filter reads it back (the shortest exact unit)."""
    for unit in ("h", "min", "s", "ms", "us"):
        q = ns / _TIME_UNITS[unit]
        if abs(q) >= 1 and q == round(q, 6):
            return f"{round(q, 6):g}{unit}"
    return f"{ns:g}ns"


@dataclass(frozen=True)
class RegRange:
    """Registers lo..hi (inclusive) of one table, or of any table (table None)."""

    table: str | None
    lo: int
    hi: int

    def overlaps(self, table: str, lo: int, hi: int) -> bool:
        """Does it share a register with `table` lo..hi-1 (a frame's range, hi exclusive)?"""
        return (self.table is None or self.table == table) and self.lo < hi and lo <= self.hi


def parse_register(s: str) -> tuple[str | None, int] | None:
    """(table or None, address) of holding[300], input[0x10], 300, 0x12C, 012CH; None if it is no register."""
    m = _TABLE_REG.match(s)
    if m:
        a = parse_int(m.group(2))
        if a is None:
            raise BadValue(f"not a register number: {m.group(2)!r}", len(m.group(1)) + 1)
        return m.group(1).lower(), a
    a = parse_int(s)
    if a is None or s.startswith(("+", "-")):
        return None
    return None, a


def looks_like_register(word: str) -> bool:
    """Would a user mean a register by this free-text word?  Numbers without a leading zero (300,
    not the hex text 0103), 0x12C, 012CH and holding[300]."""
    if _DEC.match(word):
        return word[0] not in "+-" and (word == "0" or word[0] != "0")
    try:
        return parse_register(word) is not None
    except BadValue:
        return False


def split_range(s: str) -> tuple[str, str] | None:
    """("lo", "hi") of lo..hi (either may be empty), or None without '..'."""
    lo, sep, hi = s.partition("..")
    return (lo, hi) if sep else None


@dataclass(frozen=True)
class Interval:
    """lo..hi of numbers, either end open (None) or exclusive."""

    lo: float | None = None
    hi: float | None = None
    lo_excl: bool = False
    hi_excl: bool = False

    def __contains__(self, v) -> bool:
        lo, hi = self.lo, self.hi
        if lo is not None and (v < lo or (self.lo_excl and v == lo)):
            return False
        return hi is None or not (v > hi or (self.hi_excl and v == hi))

    @property
    def point(self):
        """Its one value when lo == hi (both ends in), else None."""
        return self.lo if self.lo is not None and self.lo == self.hi and not self.lo_excl else None


def comparison_intervals(op: str, v: float) -> tuple[Interval, ...]:
    """The values `x op v` holds for (op one of > >= < <= = == !=)."""
    if op in ("=", "=="):
        return (Interval(v, v),)
    if op == "!=":
        return Interval(hi=v, hi_excl=True), Interval(lo=v, lo_excl=True)
    return {">": (Interval(lo=v, lo_excl=True),), ">=": (Interval(lo=v),),
            "<": (Interval(hi=v, hi_excl=True),), "<=": (Interval(hi=v),)}[op]
