"""Exact decimal seconds -> integer nanoseconds (no float rounding)."""

from __future__ import annotations


def seconds_to_ns(text: str) -> int:
    text = text.strip()
    neg = text.startswith("-")
    if neg:
        text = text[1:]
    if "e" in text or "E" in text:
        from decimal import Decimal

        v = int((Decimal(text) * 1_000_000_000).to_integral_value())
        return -v if neg else v
    whole, _, frac = text.partition(".")
    if not (whole or frac) or not (whole.isdigit() or whole == "") or not (frac.isdigit() or frac == ""):
        raise ValueError(f"not a number of seconds: {text!r}")
    ns = int(whole or "0") * 1_000_000_000 + int((frac + "000000000")[:9])
    if len(frac) > 9 and int(frac[9]) >= 5:
        ns += 1
    return -ns if neg else ns
