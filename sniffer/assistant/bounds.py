"""What an assistant is given is bounded and inert: bus text stripped of control characters and capped, lists
and answers capped in count and bytes.

Names, ASCII payloads and decoded texts come from the bus, which anyone with a wire on it can write: they reach
the assistant as data (JSON strings), never as terminal control sequences or pages of text.
"""

from __future__ import annotations

import json
import math
import re

TEXT_CAP = 200  # characters of one string from the bus (a register's name, a decoded text, a summary)
LIST_CAP = 200  # items of one list inside an answer (a frame's points, a table's rows)
ANSWER_BYTES = 64_000  # the JSON of one answer, at most (frames and rows are dropped past it, and said so)
# C0 and C1 controls, DEL, and the Unicode marks that reorder or hide text (bidi overrides, zero-width)
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2060-\u2064\u2066-\u2069\ufeff]")


def clean(text: str, cap: int = TEXT_CAP) -> str:
    """`text` with every control character a space, cut to `cap` characters (marked with an ellipsis)."""
    text = _CONTROL.sub(" ", text)
    return text if len(text) <= cap else text[:cap - 1] + "…"


def scrub(value, cap: int = TEXT_CAP, items: int = LIST_CAP):
    """A JSON-ready copy of `value`: strings cleaned, lists and dicts cut to `items` entries, bytes as hex,
    non-finite floats as None (JSON has no NaN)."""
    if isinstance(value, str):
        return clean(value, cap)
    if isinstance(value, bool) or value is None or isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (bytes, bytearray, memoryview)):
        return clean(bytes(value).hex(), cap)
    if isinstance(value, dict):
        return {clean(str(k), cap): scrub(v, cap, items) for k, v in list(value.items())[:items]}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [scrub(v, cap, items) for v in list(value)[:items]]
    return clean(str(value), cap)


def size(value) -> int:
    """Bytes of `value` as JSON (what the assistant receives)."""
    return len(json.dumps(value, ensure_ascii=False, default=str).encode())


def fit(rows: list, budget: int) -> tuple[list, bool]:
    """The first rows whose JSON fits in `budget` bytes (at least none); and whether any was left out."""
    kept, used = [], 2
    for row in rows:
        n = size(row) + 1
        if used + n > budget:
            return kept, True
        kept.append(row)
        used += n
    return kept, False


def bounded(name: str, value: int | float | None, default, low, high):
    """An assistant's count or time argument, within [low, high] (its default when not given); ValueError
    naming the argument for anything else."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} must be a number from {low} to {high}")
    if not low <= value <= high:
        raise ValueError(f"{name} must be from {low} to {high}, not {value}")
    return value
