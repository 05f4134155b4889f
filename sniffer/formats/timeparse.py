"""Exact decimal seconds -> integer nanoseconds (no float rounding).

Accepted: `[+-]digits[.digits][e[+-]digits]`, e.g. `0.000937`, `-1.5`,
`1.2e-3`.  Rejected with ValueError: anything else (`1e`, `nan`, `inf`,
`0x10`, empty), text over MAX_TEXT characters, an exponent beyond
+-MAX_EXPONENT (so `1e999999` never builds a million-digit integer) and
values whose nanoseconds do not fit a signed 64-bit integer (about 292
years), which no capture file holds.
"""

from __future__ import annotations

import re

MAX_TEXT = 64
MAX_EXPONENT = 30
LIMIT_NS = 2**63  # |t| must stay below: int64 nanoseconds, what MCAP and pcap timestamps hold

_NUMBER = re.compile(r"([+-]?)([0-9]*)(?:\.([0-9]*))?(?:[eE]([+-]?[0-9]+))?")


def seconds_to_ns(text: str) -> int:
    """Integer nanoseconds of a decimal number of seconds, rounded half up; ValueError if not one."""
    whole, _dot, frac = text.partition(".")
    if len(whole) <= 9 and len(frac) <= 9 and whole.isdigit() and whole.isascii() \
            and (frac.isdigit() and frac.isascii() or not frac and whole):
        # the common case, e.g. 12.000937: below 10**9 s, so no range check
        return int(whole + frac + "000000000"[len(frac):])
    text = text.strip()
    whole, _dot, frac = text.partition(".")
    if whole.isdigit() and whole.isascii() and len(text) <= 30 and (frac.isdigit() and frac.isascii() or not frac):
        ns = int(whole) * 1_000_000_000 + int((frac + "000000000")[:9])
        if len(frac) > 9 and frac[9] >= "5":
            ns += 1
        if ns >= LIMIT_NS:
            raise ValueError(f"time out of range: {text!r}")
        return ns
    if len(text) > MAX_TEXT:
        raise ValueError(f"not a number of seconds ({len(text)} characters)")
    m = _NUMBER.fullmatch(text)
    if m is None or not (m.group(2) or m.group(3)):
        raise ValueError(f"not a number of seconds: {text!r}")
    sign, whole, frac, exp_text = m.group(1), m.group(2), m.group(3) or "", m.group(4)
    exp = 0
    if exp_text is not None:
        exp = int(exp_text)  # at most MAX_TEXT digits: cheap
        if abs(exp) > MAX_EXPONENT:
            raise ValueError(f"time out of range: {text!r}")
    # value = int(whole frac) * 10**(exp - len(frac)) seconds; in ns: shift by 9
    digits = int((whole + frac) or "0")
    shift = exp - len(frac) + 9
    if shift >= 0:
        ns = digits * 10**shift
    else:
        q, r = divmod(digits, 10**-shift)
        ns = q + (1 if 2 * r >= 10**-shift else 0)
    if ns >= LIMIT_NS:
        raise ValueError(f"time out of range: {text!r}")
    return -ns if sign == "-" else ns
