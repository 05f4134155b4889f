"""Which per-frame path runs: the compiled one (sniffer._hot, from sniffer/_hot.c) or the pure-Python one.

The pure-Python functions are the reference; each compiled function is a copy of one of them, swapped in
where it is called (framing/rtu.py, formats/mcap/scan.py, formats/mcap/format.py, decoders/generic/decoder.py;
analysis/linehealth.py holds a C type, Health, under its LineHealth), and it hands back to the
Python code every case it does not decide.  tests/test_hot_equal.py holds both paths byte for byte.
SNIFFER_PURE=1 in the environment runs the pure-Python path (with the extension built); without a
compiler at install time it is the only one.  `sniffer --version` says which path runs, and why.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType


def _load() -> tuple[ModuleType | None, str]:
    if os.environ.get("SNIFFER_PURE", "") not in ("", "0"):
        return None, "SNIFFER_PURE is set"
    try:
        return importlib.import_module("sniffer._hot"), ""  # built beside the package: not a module of ours
    except ImportError as e:
        return None, f"sniffer._hot is not built: {e}"


HOT, WHY_PURE = _load()


def describe() -> str:
    """One line: which path runs (and why the pure one, when it does)."""
    if HOT is not None:
        return "hot path: compiled (sniffer._hot)"
    return f"hot path: pure Python ({WHY_PURE})"
