"""What the register-map importers share: address notations, type and word-order names, reading a file.

Every importer turns its rows into rows of the TOML format (docs/register-map-format.md) and
hands them to `decoders.tables.map_from_doc`, which checks them as it checks a TOML file; an
error names the imported file and its line.
"""

from __future__ import annotations

import os
import re

from ..tables import MapError

# --map-base / `# base:`: how the file counts its addresses
BASES = ("0", "1", "modicon")

# data type names plants use -> (type, word_order or None, byte_order or None)
_TYPES = {
    "u16": "u16", "uint16": "u16", "uint": "u16", "word": "u16", "unsigned": "u16", "ushort": "u16",
    "s16": "s16", "int16": "s16", "int": "s16", "short": "s16", "signed": "s16", "i16": "s16",
    "u32": "u32", "uint32": "u32", "udint": "u32", "dword": "u32", "ulong": "u32",
    "s32": "s32", "int32": "s32", "dint": "s32", "long": "s32", "i32": "s32",
    "u64": "u64", "uint64": "u64", "ulint": "u64", "s64": "s64", "int64": "s64", "lint": "s64", "i64": "s64",
    "float32": "f32", "float": "f32", "f32": "f32", "real": "f32", "single": "f32",
    "f64": "f64", "float64": "f64", "double": "f64", "lreal": "f64",
    "str": "str", "string": "str", "ascii": "str", "char": "str",
}
# byte-order letters of a 32-bit value as plant documents write them -> (word_order, byte_order)
ORDERS = {
    "abcd": ("big", "big"), "cdab": ("little", "big"), "badc": ("big", "little"), "dcba": ("little", "little"),
    "big": ("big", "big"), "little": ("little", "little"),
    "be": ("big", "big"), "le": ("little", "little"),
    "word_swap": ("little", "big"), "byte_swap": ("big", "little"),
}
_ORDER_SUFFIX = re.compile(r"^(?P<t>[a-z0-9]+?)[_ ]?(?P<o>abcd|cdab|badc|dcba|be|le)$")


def read_text(path: str) -> str:
    """The file as text (UTF-8, a BOM allowed), or MapError naming it (decoders.tomlfile.read_text's checks)."""
    from decoders.tomlfile import read_text as read_small_text

    return read_small_text(path, MapError, "a register map", bom=True)


def parse_base(text, what: str) -> str:
    t = str(text).strip().lower()
    if t not in BASES:
        raise ValueError(f"{what} {str(text)[:40]!r}: one of 0, 1, modicon")
    return t


def parse_type(text: str) -> tuple[str, str | None, str | None]:
    """'uint16' -> ('u16', None, None); 'float32_cdab' -> ('float32', 'little', 'big'); ValueError if unknown."""
    t = str(text).strip().lower().replace("-", "_")
    if not t:
        return "u16", None, None
    if t in _TYPES:
        return _TYPES[t], None, None
    m = _ORDER_SUFFIX.match(t)
    if m and m["t"] in _TYPES:
        wo, bo = ORDERS[m["o"]]
        return _TYPES[m["t"]], wo, bo
    raise ValueError(f"unknown type {str(text)[:40]!r} (e.g. u16, s16, u32, s32, float32, f64, str, "
                     f"or int16, uint32, float ... with an order suffix such as _cdab)")


def parse_order(text: str) -> tuple[str, str]:
    t = str(text).strip().lower().replace("-", "_").replace(" ", "_")
    if t not in ORDERS:
        raise ValueError(f"word order {str(text)[:40]!r} (one of ABCD, CDAB, BADC, DCBA, big, little)")
    return ORDERS[t]


_HEX_H = re.compile(r"^([0-9a-f]+)h$")


def parse_address(text, base: str) -> int:
    """A register address as written in a map ('0x2524', '2524H', '9508', Modicon '40001') -> the PDU
    address (0-based); ValueError with the reason if it is none."""
    if isinstance(text, bool):
        raise ValueError(f"address {text!r} is not a number")
    if isinstance(text, int):
        t, n, hexa = str(text), text, False
    else:
        t = str(text).strip().lower().replace("_", "")
        m = _HEX_H.match(t)
        if t.startswith("0x") and len(t) > 2 and all(c in "0123456789abcdef" for c in t[2:]):
            n, hexa = int(t, 16), True
        elif m:
            n, hexa = int(m[1], 16), True
        elif t.isascii() and t.isdigit():
            n, hexa = int(t, 10), False
        else:
            raise ValueError(f"address {str(text)[:40]!r} is not a number (decimal, 0x2524 or 2524H)")
    if base == "modicon":
        if hexa:
            raise ValueError(f"address {str(text)[:40]!r}: Modicon addresses are decimal (40001, 30001)")
        for lo, hi in ((30001, 39999), (40001, 49999), (300001, 365536), (400001, 465536)):
            if lo <= n <= hi:
                return n - lo
        raise ValueError(f"address {str(text)[:40]!r} is not a Modicon register (3xxxx input, 4xxxx holding)")
    if base == "1":
        if n < 1:
            raise ValueError(f"address {str(text)[:40]!r}: addresses count from 1 here (--map-base 1)")
        n -= 1
    if n > 0xFFFF:
        hint = " (Modicon notation? give --map-base modicon)" if 300001 <= n <= 465536 else ""
        raise ValueError(f"address {str(text)[:40]!r} is past 0xFFFF{hint}")
    return n


def parse_number(text, what: str, comma_decimal: bool = False) -> float | int:
    """'0.1' -> 0.1, '10' -> 10, '0,1' -> 0.1 where a comma is the decimal mark; ValueError if not a number."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        v = text
    else:
        t = str(text).strip()
        if comma_decimal and "," in t and "." not in t:
            t = t.replace(",", ".")
        try:
            v = int(t)
        except ValueError:
            try:
                v = float(t)
            except ValueError:
                raise ValueError(f"{what} {str(text)[:40]!r} is not a number") from None
    if isinstance(v, float) and v != v or v in (float("inf"), float("-inf")):
        raise ValueError(f"{what} {str(text)[:40]!r} is not a finite number")
    return v


def model_id_of(path: str) -> str:
    """The model id of a map file that names none: its stem (`meters/sdm230.csv` -> `sdm230`)."""
    return os.path.splitext(os.path.basename(path))[0] or "map"
