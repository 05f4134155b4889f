"""PD-series DATA layouts in construct, by function, role and number of DATA bytes (schema.py's
functions, bits and parameters as construct Structs; the manual's lines are cited there and here).

Kept apart from schema.py so that importing the decoders (every command does) does not import
construct: 8 MB of RSS and 40 ms, paid only when a PD frame is decoded.
"""

from __future__ import annotations

from construct import BitStruct, Flag, GreedyBytes, Int8ub, Int16ub, Struct

from .schema import CNST_BITS, CNTR_BITS, REQ, RSP, Bit


def _bits(bits: tuple[Bit, ...]) -> BitStruct:
    return BitStruct(*[b.name / Flag for b in sorted(bits, key=lambda b: -b.bit)])  # MSB first


CNTR = _bits(CNTR_BITS)
CNST = _bits(CNST_BITS)


# ---- DATA layouts, by function, role and number of DATA bytes ----------------
ParamOnly = Struct("param" / Int8ub)  # read request without value bytes (l.97)
ParamByte = Struct("param" / Int8ub, "value" / Int8ub)  # LEN=2 (l.107)
ParamWord = Struct("param" / Int8ub, "value" / Int16ub)  # LEN=3, high byte first (l.107, l.179)
Control = Struct("cntr" / CNTR)  # l.131
ControlStatus = Struct("cnst" / CNST)  # l.144, and 83H (l.153)
StatusRequest = Struct("cfg" / Int8ub)  # l.159 "ADDR 04 01 CFG"
StatusRequestPadded = Struct("cfg" / Int8ub, "pad" / Int16ub)  # LEN=3 as in the l.173 example
StatusWord = Struct("value" / Int16ub)  # l.175 example: "13 88 are data"
StatusByte = Struct("value" / Int8ub)
StatusFull = Struct("cfg" / Int8ub, "value" / Int16ub)  # CFG echoed + word (LEN=3)
Frequency = Struct("frequency" / Int16ub)  # 05H: format not printed; a word as in 02H
FrequencyPadded = Struct("pad" / Int8ub, "frequency" / Int16ub)  # "one word -> LEN=3" (l.181) taken literally
LoopTest = Struct("data" / GreedyBytes)  # 08H: format not printed
ParamError = Struct("param" / Int8ub)  # 81H 01 FUNC (l.111, l.125)

_PARAM = {1: ParamOnly, 2: ParamByte, 3: ParamWord}
LAYOUTS: dict[tuple[int, str], dict[int, Struct]] = {
    (0x01, REQ): _PARAM,
    (0x01, RSP): _PARAM,
    (0x02, REQ): _PARAM,
    (0x02, RSP): _PARAM,
    (0x03, REQ): {1: Control},
    (0x03, RSP): {1: ControlStatus},
    (0x04, REQ): {1: StatusRequest, 3: StatusRequestPadded},
    (0x04, RSP): {1: StatusByte, 2: StatusWord, 3: StatusFull},
    (0x05, REQ): {2: Frequency, 3: FrequencyPadded},
    (0x05, RSP): {2: Frequency, 3: FrequencyPadded},
    (0x81, RSP): {1: ParamError},
    (0x83, RSP): {1: ControlStatus},
}


def layout_for(fc: int, role: str, n: int) -> tuple[Struct | None, int]:
    """(layout, bytes it reads) for n DATA bytes: the exact size, else the largest that fits, else None."""
    if fc == 0x08:
        return LoopTest, n
    sizes = LAYOUTS.get((fc, role))
    if sizes is None:
        return None, 0
    if n in sizes:
        return sizes[n], n
    fits = [k for k in sizes if k <= n]
    if not fits:
        return None, 0
    k = max(fits)
    return sizes[k], k
