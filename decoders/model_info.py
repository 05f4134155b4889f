"""A register map's [model] table as one typed structure, `ModelInfo`, checked in one place (`from_table`).

The keys the decoders, the identifier and the simulator read are fields, each declared with what
its value must be and its check, as strictly as a register row's fields: a map with
`function_codes = 3` is one line naming the key, not a traceback when a decoder first reads it.
Readers take attributes (`info.function_codes`, `info.mode_register.bit`), never `.get()` with a
default of their own.  The manual's notes (keys nothing reads, NOTES) are kept as written, in
`table` with every other key (what `mapformats/tomlout.py` writes back).  Any other key is refused,
as an unknown key of a row is.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields

from .regtypes import ORDERS

MAX_REGISTERS = 0x10000  # every address once


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def is_number(v) -> bool:
    return (is_int(v) or isinstance(v, float)) and math.isfinite(v)


def _int_in(lo: int, hi: int):
    return lambda v: is_int(v) and lo <= v <= hi


def _list_of(ok):
    return lambda v: isinstance(v, list) and all(ok(x) for x in v)


def _table_of(required: dict, optional: dict | None = None):
    """A table with the `required` keys, each passing its check, and maybe the `optional` ones."""
    optional = optional or {}
    return lambda v: (isinstance(v, dict) and all(k in v and ok(v[k]) for k, ok in required.items())
                      and all(ok(v[k]) for k, ok in optional.items() if k in v))


_ADDR = _int_in(0, 0xFFFF)
_TEXT = lambda v: isinstance(v, str)  # noqa: E731 - one line in a table of checks
_NUMBER = lambda v: is_number(v) and v >= 0  # noqa: E731
_RANGE = lambda v: isinstance(v, list) and len(v) == 2 and all(_ADDR(x) for x in v) and v[0] <= v[1]  # noqa: E731
_UNITS = lambda v: isinstance(v, list) and len(v) == 2 and all(_int_in(0, 255)(x) for x in v) and v[0] <= v[1]  # noqa: E731
_ORDER = lambda v: v in ORDERS  # noqa: E731


@dataclass(frozen=True, slots=True)
class Marker:
    """A raw value of a register that is no measurement (`not_available`): shown as its text."""

    addr: int
    raw: int
    text: str
    section: str = ""


@dataclass(frozen=True, slots=True)
class ModeRegister:
    """The status register and bit that say DRV (1) or PRG (0) mode."""

    addr: int
    bit: int


@dataclass(frozen=True, slots=True)
class ModeCommand:
    """The command register's bits that switch to DRV and to PRG mode."""

    addr: int
    to_drv_bit: int
    to_prg_bit: int


@dataclass(frozen=True, slots=True)
class EepromSave:
    """The write that saves the parameters to EEPROM (`value` to `addr`), and the parameter groups it keeps
    (TDS-V8: a save in DRV mode keeps An and bn, in PRG mode also Cn and Sn)."""

    addr: int
    value: int
    saves_in_drv: tuple = ()
    saves_in_prg: tuple = ()


@dataclass(frozen=True, slots=True)
class FrequencyScale:
    """The register whose value is 100 % of a frequency command (`full` counts)."""

    addr: int
    full: float


def _key(must: str, check: Callable[[object], bool], convert: Callable | None = None, default=None):
    """A [model] key: what its value must be (said in the error line), its check, how it becomes the field."""
    return field(default=default, metadata={"must": must, "check": check, "convert": convert})


def _ints(v) -> tuple[int, ...]:
    return tuple(v)


def _ranges(v) -> tuple[tuple[int, int], ...]:
    return tuple((lo, hi) for lo, hi in v)


def _of(cls):
    return lambda v: cls(**{f.name: v[f.name] for f in fields(cls) if f.name in v})


_INTS_1_255 = ("a list of integers 1..255", _list_of(_int_in(1, 255)), _ints)
_REGISTERS = ("a list of integers", _list_of(_ADDR), _ints)
_MS = ("a number of ms", _NUMBER, float)
_UNIT_PAIR = ("[lowest, highest] unit address (0..255)", _UNITS, tuple)
_RANGES = ("a list of [first, last] registers", _list_of(_RANGE), _ranges)


@dataclass(frozen=True)
class ModelInfo:
    """The [model] table: what a drive model is and can do, as its manual says (None: the map does not say)."""

    id: str = _key("a non-empty string", lambda v: isinstance(v, str) and bool(v.strip()))
    name: str | None = _key("a string", _TEXT)
    manual: str | None = _key("a string", _TEXT)
    revision: str | None = _key("a string", _TEXT)
    manuals: tuple[str, ...] = _key("a list of strings", _list_of(_TEXT), tuple, ())
    protocols: tuple[str, ...] = _key("a list of strings", _list_of(_TEXT), tuple, ())
    bauds: tuple[int, ...] = _key("a list of integers", _list_of(_int_in(1, 100_000_000)), _ints, ())
    default_baud: int | None = _key("an integer in 1..100000000", _int_in(1, 100_000_000))
    # the rows' defaults; and how an exception code outside the manual's table is taken
    word_order: str = _key("big or little", _ORDER, None, "big")
    byte_order: str = _key("big or little", _ORDER, None, "big")
    exception_table: str = _key("standard or complete", lambda v: v in ("standard", "complete"), None, "standard")
    max_registers_per_request: int | None = _key(f"an integer in 1..{MAX_REGISTERS}", _int_in(1, MAX_REGISTERS))
    max_frame_bytes: int | None = _key(f"an integer in 4..{1 << 16}", _int_in(4, 1 << 16))
    function_codes: tuple[int, ...] | None = _key(*_INTS_1_255)  # None (or []): any function
    vendor_function_codes: tuple[int, ...] = _key(*_INTS_1_255, ())
    loopback_subfunctions: tuple[int, ...] | None = _key("a list of integers 0..0xFFFF", _list_of(_ADDR), _ints)
    broadcast_registers: tuple[int, ...] | None = _key(*_REGISTERS)  # None: any register may be broadcast
    fault_registers: tuple[int, ...] = _key(*_REGISTERS, ())
    alarm_registers: tuple[int, ...] = _key(*_REGISTERS, ())
    not_available: tuple[Marker, ...] = _key(
        "a list of { addr, raw (0..0xFFFF), text }",
        _list_of(_table_of({"addr": _ADDR, "raw": _ADDR, "text": _TEXT}, {"section": _TEXT})),
        lambda v: tuple(_of(Marker)(x) for x in v), ())
    unit_addresses: tuple[int, int] | None = _key(*_UNIT_PAIR)
    unit_address_range: tuple[int, int] | None = _key(*_UNIT_PAIR)
    broadcast_address: int | None = _key("an integer in 0..255", _int_in(0, 255))
    prg_only_ranges: tuple[tuple[int, int], ...] = _key(*_RANGES, ())
    any_mode_ranges: tuple[tuple[int, int], ...] = _key(*_RANGES, ())
    mode_register: ModeRegister | None = _key("{ addr, bit (0..15) }",
                                              _table_of({"addr": _ADDR, "bit": _int_in(0, 15)}), _of(ModeRegister))
    mode_command: ModeCommand | None = _key(
        "{ addr, to_drv_bit, to_prg_bit (0..15) }",
        _table_of({"addr": _ADDR, "to_drv_bit": _int_in(0, 15), "to_prg_bit": _int_in(0, 15)}), _of(ModeCommand))
    eeprom_save: EepromSave | None = _key(
        "{ addr, value (0..0xFFFF), saves_in_drv, saves_in_prg (lists of parameter groups) }",
        _table_of({"addr": _ADDR, "value": _ADDR}, {"saves_in_drv": _list_of(_TEXT), "saves_in_prg": _list_of(_TEXT)}),
        lambda v: EepromSave(v["addr"], v["value"], tuple(v.get("saves_in_drv", ())), tuple(v.get("saves_in_prg", ()))))
    frequency_scale: FrequencyScale | None = _key(
        "{ addr, full (a positive number) }", _table_of({"addr": _ADDR, "full": lambda v: is_number(v) and v > 0}),
        _of(FrequencyScale))
    response_delay_ms: float | None = _key(*_MS)
    response_time_ms: float | None = _key(*_MS)
    response_timeout_ms: float | None = _key(*_MS)
    turnaround_ms: float | None = _key(*_MS)
    table: Mapping = field(default_factory=dict, compare=False, repr=False)  # as written: the notes too

    @property
    def units(self) -> tuple[int, int] | None:
        """The unit addresses the model can have, [lowest, highest] (either key of the manual's wording)."""
        return self.unit_addresses or self.unit_address_range

    @classmethod
    def from_table(cls, table, error: Callable[[str], Exception], top_level: tuple[str, ...] = ()) -> ModelInfo:
        """The [model] table checked, as a ModelInfo; `error(text)` makes the one-line error raised for a key
        that is unknown or of the wrong kind (`top_level`: the file's other tables, which TOML puts under
        [model] when their keys follow its header)."""
        if not isinstance(table, dict) or not table.get("id"):
            raise error("no [model] table with an id")
        for key in top_level:
            if key in table:
                raise error(f"[model]: {key} sits under [model]; write `{key} = ...` before the first [table] (TOML "
                            f"puts it in the table above it)")
        unknown = sorted(str(k) for k in table if k not in KEYS and k not in NOTES)
        if unknown:
            near = difflib.get_close_matches(unknown[0], [*KEYS, *NOTES], n=1)
            raise error(f"[model]: unknown key {_show(unknown[0])}" + (f" (did you mean {near[0]}?)" if near else
                                                                     " (docs/register-map-format.md lists the keys)"))
        for f in ("word_order", "byte_order"):  # the defaults of the rows: said as a row's are
            if f in table and not _ORDER(table[f]):
                raise error(f"[model]: {f} {_show(table[f])} (big or little)")
        if table.get("exception_table", "standard") not in ("standard", "complete"):
            raise error(f"[model]: exception_table {_show(table['exception_table'])} (standard or complete)")
        values = {}
        for key, value in table.items():
            f = KEYS.get(key)
            if f is None:
                continue
            if not f.metadata["check"](value):
                raise error(f"[model]: {key} must be {f.metadata['must']}, not {_show(value)}")
            convert = f.metadata["convert"]
            values[key] = convert(value) if convert else value
        return cls(**values, table=dict(table))

    def to_table(self) -> dict:
        """The [model] table to write: as it was read, or (built in code) the keys that say something."""
        if self.table:
            return dict(self.table)
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name != "table" and v is not None and v != f.default:
                out[f.name] = _plain(v)
        return out


def _plain(v):
    """A field's value as TOML holds it (lists, tables)."""
    if isinstance(v, tuple):
        return [_plain(x) for x in v]
    if hasattr(v, "__dataclass_fields__"):
        return {f.name: getattr(v, f.name) for f in fields(v) if getattr(v, f.name) not in ("", None)}
    return v


def brief(v, limit: int = 60) -> str:
    """`v`'s repr for an error line, at most `limit` characters (never the whole of a huge value)."""
    import reprlib

    r = reprlib.Repr()
    r.maxlevel, r.maxstring, r.maxother = 4, limit, limit
    text = r.repr(v)
    return text if len(text) <= limit else text[:limit] + "..."


def _show(v) -> str:
    return brief(v, 60)


KEYS = {f.name: f for f in fields(ModelInfo) if f.name != "table"}  # every key read, with its check
# [model] keys that only note what the manual says (nothing reads them): kept as written
NOTES = frozenset({
    "ascii_frame", "bauds_by_revision", "char_bits", "comm_timeout_param", "crc_low_byte_first",
    "exception_function", "loopback_test_code", "max_drives_on_bus", "no_response", "parity", "physical",
    "prg_only_groups", "retries", "scale_rules", "write_rules",
})
