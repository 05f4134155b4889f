"""What the decoders know that scales or names values, carried from one part of a capture into the next.

A capture is cut into parts that are read alone: rotated segments, trigger windows, the files a
fleet dataset takes in.  A value whose scale depends on what the decoders learnt earlier (TDS-V8
frequencies are % of Cn-02; an A510 shown to run at 0.1 Hz per count; a unit's model, identified
from its answers) must not change its unit or name at a cut, so every part starts with what the
decoders knew when it was cut: the `decoder_state` of its metadata (CaptureInfo.extra[KEY]),
by link ("" on one line), then unit:

    {"": {"1": {"model": "tds-v8", "confidence": 0.94,      # identified (never the user's map)
                "holding": {"769": 600},                    # registers that scale others, raw
                "extra": {"mode": "DRV"}}}}                 # settings the traffic showed

`DecoderRegistry.carried()` makes a link's part, `carry_in()` starts a registry with it; a bus
file's `[parameters]` (values the bus may never show, by the manual's id: `"Cn-02" = 60`) are
put in after it by `DecoderRegistry.preset` (the user's word wins, the bus's later reads win
over both).  A replay of a folder carries it across its segments by itself (one pipeline), and
where a segment is missing it takes the next one's (a Gap with `state`, sources/segset.py).
"""

from __future__ import annotations

import math
import re

KEY = "decoder_state"
_VALUE = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?)\s*(\S*)\s*\Z", re.I)


def of_info(info, link: str = "") -> dict:
    """The units' carried state a capture's metadata gives for `link` ({} if none)."""
    if info is None:
        return {}
    d = info.extra.get(KEY)
    part = d.get(link) if isinstance(d, dict) else None
    return part if isinstance(part, dict) else {}


def record(info, state: dict) -> None:
    """Put a capture's state ({link: {unit: ...}}) into its metadata; no key when nothing is known."""
    state = {link: units for link, units in state.items() if units}
    if state:
        info.extra[KEY] = state
    else:
        info.extra.pop(KEY, None)


def param_raw(r, value, model: str) -> int:
    """The raw register value of a parameter stated in the register's unit: 60, 60.0 or "60 Hz" for
    Cn-02 (0.1 Hz per count) is 600.  ValueError (one line) for a value that does not read, has another
    unit, or does not fit the register (its manual range, its width)."""
    what = f"{model} {r.id or r.name}"
    unit = ""
    if isinstance(value, str):
        m = _VALUE.match(value)
        if not m:
            raise ValueError(f"{what} = {value!r}: not a number (e.g. 60 or \"60 {r.unit or 'Hz'}\")")
        value, unit = float(m.group(1)), m.group(2)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{what} = {value!r}: not a number")
    if unit and unit.lower() != (r.unit or "").lower():
        raise ValueError(f"{what} is in {r.unit or 'no unit'}, not {unit}")
    if r.scale_by or r.scale_rule or r.type not in ("u16", "s16"):
        raise ValueError(f"{what}: only a plain 16-bit register can be given (this one is {r.type}"
                         f"{', scaled through another' if r.scale_by or r.scale_rule else ''})")
    raw = value / r.scale if r.scale else value
    n = round(raw)
    if abs(raw - n) > 1e-6 * max(1.0, abs(raw)):
        raise ValueError(f"{what} = {value}: not a whole number of {r.scale:g} {r.unit}".rstrip())
    if (r.min is not None and n < r.min) or (r.max is not None and n > r.max):
        raise ValueError(f"{what} = {value}: outside the manual's range {r.min}..{r.max} (raw)")
    lo, hi = (-0x8000, 0x7FFF) if r.type == "s16" else (0, 0xFFFF)
    if not lo <= n <= hi:
        raise ValueError(f"{what} = {value}: does not fit a {r.type}")
    return n & 0xFFFF
