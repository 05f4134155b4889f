"""The trigger flags of a capture (`--trigger`, `--pre`, `--post`, `--ring` ...), checked once: TriggerSpec."""

from __future__ import annotations

import re
from dataclasses import dataclass

from sniffer.filterlang import FilterError, Query
from sniffer.filterlang.values import BadValue, parse_duration
from sniffer.line import SettingsError

DEFAULT_PRE_S = 300.0
DEFAULT_POST_S = 60.0
DEFAULT_RING_BYTES = 64 * 1024 * 1024
DEFAULT_COMMAND_TIMEOUT_S = 60.0
MAX_SPAN_S = 24 * 3600.0
_SIZE = re.compile(r"(\d+(?:\.\d+)?)\s*(b|kb|kib|mb|mib|gb|gib)?\Z", re.I)
_SIZE_UNIT = {"": 1, "b": 1, "kb": 10**3, "kib": 2**10, "mb": 10**6, "mib": 2**20, "gb": 10**9, "gib": 2**30}


def seconds(text, flag: str) -> float:
    """Seconds of `5m`, `90s`, `1.5h`, `300ms` or a bare number of seconds (the command line gives a number
    already: commands/flags.py duration); SettingsError otherwise."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        v = float(text)
    else:
        try:
            v = parse_duration(str(text), "s") / 1e9
        except BadValue as e:
            raise SettingsError(f"{flag} {str(text)[:40]!r}: {e}") from None
    if not 0 <= v <= MAX_SPAN_S:
        raise SettingsError(f"{flag} {str(text)[:40]!r}: from 0 to 24h")
    return v


def size_bytes(text, flag: str) -> int:
    """Bytes of `64MB`, `512KiB`, `1GB` or a bare number of bytes; SettingsError otherwise."""
    m = _SIZE.match(str(text).strip())
    if not m:
        raise SettingsError(f"{flag} {str(text)[:40]!r}: not a size (64MB, 512KiB, 1GB)")
    return int(float(m.group(1)) * _SIZE_UNIT[(m.group(2) or "").lower()])


def check_rule(text: str) -> Query:
    """The rule's query; SettingsError naming the flag and the column for one that does not parse."""
    try:
        q = Query(text)
    except FilterError as e:
        raise SettingsError(f"--trigger {text[:80]!r}: {e}") from None
    if not q:
        raise SettingsError("--trigger '': an empty rule would fire on every frame (give a filter, e.g. fault)")
    return q


@dataclass(frozen=True)
class TriggerSpec:
    rules: tuple[str, ...]
    pre_s: float = DEFAULT_PRE_S
    post_s: float = DEFAULT_POST_S
    ring: bool = False  # only the windows are kept, not the whole capture
    ring_bytes: int = DEFAULT_RING_BYTES
    max_window_s: float | None = None  # None: 10 x post
    windows: str | None = None  # the folder for window files (None: beside --out, or here)
    on_trigger: str | None = None
    on_trigger_timeout_s: float = DEFAULT_COMMAND_TIMEOUT_S

    @classmethod
    def from_args(cls, args) -> TriggerSpec | None:
        """The spec of the parsed flags, None without --trigger; SettingsError for what cannot work."""
        def opt(name, default=None):
            return getattr(args, name, default)

        rules = tuple(opt("trigger") or ())
        if not rules:
            for flag, name in (("--ring", "ring"), ("--on-trigger", "on_trigger"), ("--pre", "pre"), ("--post", "post"),
                               ("--windows", "windows")):
                if opt(name) is not None and opt(name) is not False and opt(name) != "":
                    raise SettingsError(f"{flag} needs --trigger (a rule that says when to keep a window)")
            return None
        for r in rules:
            check_rule(r)
        def given(name, default):
            v = opt(name)
            return default if v is None or v == "" else v

        post = seconds(given("post", DEFAULT_POST_S), "--post")
        max_window = None if opt("max_window") is None else seconds(opt("max_window"), "--max-window")
        if max_window is not None and max_window < post:
            raise SettingsError(f"--max-window {max_window:g}s is shorter than --post ({post:g}s)")
        ring_bytes = size_bytes(opt("ring_max") or DEFAULT_RING_BYTES, "--ring-max")
        if ring_bytes < 1 << 20:
            raise SettingsError(f"--ring-max {opt('ring_max')}: at least 1MiB")
        return cls(rules, seconds(given("pre", DEFAULT_PRE_S), "--pre"), post, bool(opt("ring")), ring_bytes,
                   max_window, opt("windows"), opt("on_trigger"),
                   seconds(given("on_trigger_timeout", DEFAULT_COMMAND_TIMEOUT_S), "--on-trigger-timeout"))


__all__ = ["TriggerSpec", "check_rule", "seconds", "size_bytes"]
