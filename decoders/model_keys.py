"""The keys of a register map's [model] table and what each value must be (decoders.tables checks them).

The keys the decoders, the identifier and the simulator read are checked as strictly as a
register row's fields: a map with `function_codes = 3` is one line naming the key, not a
traceback when a decoder first reads it.  The manual's notes (keys nothing reads) are kept as
written.  Any other key is refused, as an unknown key of a row is.
"""

from __future__ import annotations

import math

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

# [model]: the keys the decoders, the identifier and the simulator read, each checked as a row's fields are
# (name -> (what it must be, the check)); word_order, byte_order and exception_table are checked by name
MODEL_KEYS = {
    "id": ("a non-empty string", lambda v: isinstance(v, str) and bool(v.strip())),
    "name": ("a string", _TEXT), "manual": ("a string", _TEXT), "revision": ("a string", _TEXT),
    "manuals": ("a list of strings", _list_of(_TEXT)),
    "protocols": ("a list of strings", _list_of(_TEXT)),
    "bauds": ("a list of integers", _list_of(_int_in(1, 100_000_000))),
    "default_baud": ("an integer in 1..100000000", _int_in(1, 100_000_000)),
    "word_order": ("big or little", lambda v: v in ORDERS), "byte_order": ("big or little", lambda v: v in ORDERS),
    "exception_table": ("standard or complete", lambda v: v in ("standard", "complete")),
    "max_registers_per_request": (f"an integer in 1..{MAX_REGISTERS}", _int_in(1, MAX_REGISTERS)),
    "max_frame_bytes": (f"an integer in 4..{1 << 16}", _int_in(4, 1 << 16)),
    "function_codes": ("a list of integers 1..255", _list_of(_int_in(1, 255))),
    "vendor_function_codes": ("a list of integers 1..255", _list_of(_int_in(1, 255))),
    "loopback_subfunctions": ("a list of integers 0..0xFFFF", _list_of(_ADDR)),
    "broadcast_registers": ("a list of integers", _list_of(_ADDR)),
    "fault_registers": ("a list of integers", _list_of(_ADDR)),
    "alarm_registers": ("a list of integers", _list_of(_ADDR)),
    "not_available": ("a list of { addr, raw (0..0xFFFF), text }",
                      _list_of(_table_of({"addr": _ADDR, "raw": _ADDR, "text": _TEXT}, {"section": _TEXT}))),
    "unit_addresses": ("[lowest, highest] unit address (0..255)", _UNITS),
    "unit_address_range": ("[lowest, highest] unit address (0..255)", _UNITS),
    "broadcast_address": ("an integer in 0..255", _int_in(0, 255)),
    "prg_only_ranges": ("a list of [first, last] registers", _list_of(_RANGE)),
    "any_mode_ranges": ("a list of [first, last] registers", _list_of(_RANGE)),
    "mode_register": ("{ addr, bit (0..15) }", _table_of({"addr": _ADDR, "bit": _int_in(0, 15)})),
    "mode_command": ("{ addr, to_drv_bit, to_prg_bit (0..15) }",
                     _table_of({"addr": _ADDR, "to_drv_bit": _int_in(0, 15), "to_prg_bit": _int_in(0, 15)})),
    "eeprom_save": ("{ addr, value (0..0xFFFF) }", _table_of({"addr": _ADDR, "value": _ADDR})),
    "frequency_scale": ("{ addr, full (a positive number) }",
                        _table_of({"addr": _ADDR, "full": lambda v: is_number(v) and v > 0})),
    "response_delay_ms": ("a number of ms", _NUMBER), "response_time_ms": ("a number of ms", _NUMBER),
    "response_timeout_ms": ("a number of ms", _NUMBER), "turnaround_ms": ("a number of ms", _NUMBER),
}
# [model] keys that only note what the manual says (nothing reads them): kept as written
MODEL_NOTES = frozenset({
    "ascii_frame", "bauds_by_revision", "char_bits", "comm_timeout_param", "crc_low_byte_first",
    "exception_function", "loopback_test_code", "max_drives_on_bus", "no_response", "parity", "physical",
    "prg_only_groups", "retries", "scale_rules", "write_rules",
})
