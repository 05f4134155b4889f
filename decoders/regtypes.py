"""Register types of the map format: how many registers a value takes, and its registers -> its value.

`u16 s16` take one register, `u32 s32 f32` two, `u64 s64 f64` four; `str` takes the row's `words`
registers of ASCII text, two characters a register.  Two orders say how the registers make the
value (docs/register-map-format.md):

* word_order: which register holds the most significant word; "big" = the lowest address (as
  Modbus sends a register's high byte first), "little" = the highest address.
* byte_order: which byte of each register is the more significant; "big" = the first byte on the
  wire (standard Modbus), "little" = the second (a device that swaps the bytes of every word).

The four layouts of the 32-bit value 0xAABBCCDD on the wire (registers in address order):
big/big AABB CCDD, big/little BBAA DDCC, little/big CCDD AABB, little/little DDCC BBAA.
A string's characters follow the addresses; byte_order says which byte of a register holds the
first of its two characters ("big": the first on the wire); word_order does not apply to text.

`raw` of a value is its registers joined as one unsigned integer, most significant word and byte
first (the bit pattern: a float32 12.5 has raw 0x41480000), and for a string its bytes in text
order as hex.
"""

from __future__ import annotations

import math
from struct import Struct

WIDTH = {"u16": 1, "s16": 1, "u32": 2, "s32": 2, "f32": 2, "u64": 4, "s64": 4, "f64": 4}  # registers
TEXT = "str"  # its width is the row's `words`
TYPES = (*WIDTH, TEXT)
ALIASES = {"float32": "f32", "float64": "f64", "string": TEXT}  # other names a map may use
SIGNED = frozenset({"s16", "s32", "s64"})
FLOATS = {"f32": Struct(">f"), "f64": Struct(">d")}
ORDERS = ("big", "little")
MAX_WORDS = 125  # registers one read request may ask for (Modbus 0x03 / 0x04): a longer text is never whole
_WORDS = {">": {}, "<": {}}  # byte order -> number of words -> Struct


def canonical(type_: str) -> str:
    """A type name as the map format writes it (float32 -> f32); unknown names unchanged."""
    return ALIASES.get(type_, type_)


def _struct(byte_order: str, n: int) -> Struct:
    side = _WORDS[">" if byte_order == "big" else "<"]
    s = side.get(n)
    if s is None:
        s = side[n] = Struct(f"{'>' if byte_order == 'big' else '<'}{n}H")
    return s


def value_bytes(words: list[int], word_order: str = "big", byte_order: str = "big") -> bytes:
    """The value's bytes, most significant first, from its register words in address order."""
    seq = words if word_order == "big" or len(words) == 1 else words[::-1]
    return _struct(byte_order, len(seq)).pack(*seq)


def join(words: list[int], word_order: str = "big", byte_order: str = "big") -> int:
    """The registers of one value as an unsigned integer (the value's bit pattern)."""
    if len(words) == 1 and byte_order == "big":
        return words[0]
    return int.from_bytes(value_bytes(words, word_order, byte_order), "big")


def number(type_: str, raw: int, words: int):
    """The number a value's raw bit pattern stands for: signed types two's complement, floats IEEE 754."""
    if type_ in SIGNED:
        bits = 16 * words
        return raw - (1 << bits) if raw >> (bits - 1) else raw
    f = FLOATS.get(type_)
    if f is None:
        return raw
    v = f.unpack(raw.to_bytes(2 * words, "big"))[0]
    return shortest_f32(v) if type_ == "f32" else v


def shortest_f32(v: float) -> float:
    """The shortest decimal that is the same float32 (12.5 stays 12.5; 21.790203094 -> 21.790203)."""
    if not math.isfinite(v):
        return v
    pack = FLOATS["f32"].pack
    want = pack(v)
    for digits in range(6, 10):
        d = float(f"{v:.{digits}g}")
        try:
            if pack(d) == want:
                return d
        except OverflowError:  # rounded past the largest float32
            continue
    return v


def text(words: list[int], byte_order: str = "big") -> tuple[str, str]:
    """(raw hex, text) of a string's registers: trailing NULs and spaces dropped, non-ASCII bytes
    written as \\xNN so nothing is lost."""
    b = _struct(byte_order, len(words)).pack(*words)
    return b.hex(), b.rstrip(b"\x00 ").decode("ascii", "backslashreplace")


def raw_range(type_: str) -> tuple[int, int] | None:
    """The integers an integer type's raw value can be (min / max / default are raw values), None for
    floats and text."""
    if type_ in FLOATS or type_ == TEXT or type_ not in WIDTH:
        return None
    bits = 16 * WIDTH[type_]
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if type_ in SIGNED else (0, (1 << bits) - 1)
