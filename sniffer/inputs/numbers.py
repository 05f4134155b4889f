"""Numbers from files are finite: nan, inf and 1e400 (inf once read) mean nothing a drive or a line holds,
and they break JSON output and arithmetic further on."""

from __future__ import annotations

import math

from sniffer.inputs.errors import InputError


def finite(text, what: str, error: type[Exception] = InputError) -> float:
    """`text` as a finite float, or `error("<what> <text>: ...")`; ValueError-free for the caller."""
    try:
        x = float(text)
    except (TypeError, ValueError, OverflowError):
        raise error(f"{what} {str(text)[:40]!r} is not a number") from None
    if not math.isfinite(x):
        raise error(f"{what} {str(text)[:40]!r} is not a finite number (nan, inf and values beyond "
                    f"±1.8e308 are refused)")
    return x
