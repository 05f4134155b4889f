"""`sniffer status [FOLDER|FILE]`: how an unattended capture is doing, from its status file (sniffer.capture.status).

Exit status: 0 the capture is running (its status is fresh), 1 it ended, or
its status is stale (the process is gone, or has not written for a while),
2 no status file there (or not one: not a JSON object, over 16 MB, nested
too deep).  Sections a sink contributed that this command does not know
(e.g. `triggers`) are shown generically, one line each.  Every field is read
as the kind the capture writes; one of another kind is shown as ? and named
in one warning line.
"""

from __future__ import annotations

import calendar
import json
import math
import os
import sys
import time

from sniffer.formats.outputs import shown
from sniffer.formats.mcap.segments import STATUS_NAME, held, size_text
from sniffer.capture.settings import CaptureSpec
from sniffer.events import CaptureError
from sniffer.inputs import CAPS, open_regular
from sniffer.commands.common import EXIT_FAILED, EXIT_OK, UsageError, say
from sniffer.commands.flags import command_parser

_KNOWN = {"format", "state", "pid", "command", "source", "line", "started", "updated", "updated_ns", "every_s",
          "uptime_s", "capture_s", "frames", "bytes", "errors", "last_frame", "port", "segments", "ended", "units",
          "triggers"}
STALE_AFTER = 3  # status intervals without a write: the capture is not running
GENERIC_WIDTH = 300
UNITS_SHOWN = 32  # unit lines (`--json` has them all)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "status", help="how an unattended capture is doing: uptime, frames, errors, segments, "
                                   "disk use (its status file)",
        description="""\
            How an unattended capture (--rotate, --status) is doing, from the status file it keeps: running or
            not, uptime, frames and errors, segments and disk use, triggers.  Exit 0 running, 1 ended or
            stale (the process is gone), 2 no status file there.""",
        examples=["sniffer status /var/lib/sniffer/cab3",
                  "sniffer status cab3/status.json --json"])
    p.add_argument("path", nargs="?", default=".", help="the capture's folder or its status file (default: .)")
    p.add_argument("--json", action="store_true", help="print the status file as it is")


def run(spec: CaptureSpec, args) -> int:
    path = args.path
    if os.path.isdir(path):
        path = os.path.join(path, STATUS_NAME)
    d = read_status(path)
    if args.json:
        try:
            text = json.dumps(d, indent=1)
        except (RecursionError, ValueError) as e:
            raise UsageError(f"{shown(path)}: cannot be shown as JSON ({type(e).__name__})") from None
        print(text)
        return EXIT_OK
    st = Fields(d)
    running, state = _state(st)
    enc = getattr(sys.stdout, "encoding", None) or "utf-8"
    for label, text in lines(d, state, st):  # text from the file: what the terminal cannot show is escaped
        print(f"{label:<9} {text}".encode(enc, "backslashreplace").decode(enc, "replace"))
    if st.odd:
        say(f"warning: {shown(path)}: {', '.join(sorted(st.odd))} not as a capture writes "
            f"{'them' if len(st.odd) > 1 else 'it'} (shown as ?)")
    return EXIT_OK if running else EXIT_FAILED


MAX_STATUS_BYTES = CAPS["a status file"]


def read_status(path: str) -> dict:
    """The status file's JSON object, or UsageError (one line) saying why it is none."""
    hint = "(a capture writes it with --rotate or --status FILE)"
    if not os.path.lexists(path):
        raise UsageError(f"{shown(path)}: no such file {hint}")
    try:
        with open_regular(path) as fh:  # a FIFO or a device is refused before a byte is read
            raw = fh.read(MAX_STATUS_BYTES + 1)
    except CaptureError as e:
        raise UsageError(f"{e} {hint}") from None
    except OSError as e:
        raise UsageError(f"{shown(path)}: {e.strerror or e}") from None
    if len(raw) > MAX_STATUS_BYTES:
        raise UsageError(f"{shown(path)}: over {MAX_STATUS_BYTES >> 20} MB: not a status file {hint}")
    try:
        # NaN, Infinity, 1e400 read as no number: the field is shown as ? (as one the file lacks), --json: null
        d = json.loads(raw, parse_constant=lambda text: None, parse_float=_finite)
    except RecursionError:
        raise UsageError(f"{shown(path)}: nested too deep to be a status file {hint}") from None
    except ValueError:  # not JSON, not UTF-8
        d = None
    if not isinstance(d, dict):
        raise UsageError(f"{shown(path)}: not a status file (JSON object) {hint}")
    return d


def _finite(text: str) -> float | None:
    x = float(text)
    return x if math.isfinite(x) else None


class Fields:
    """The status file's fields, each read as the kind the capture writes (sniffer.capture.status); a field of
    another kind reads as None and is noted in `odd` (a file edited by hand, or of another program)."""

    def __init__(self, d: dict) -> None:
        self.d = d
        self.odd: set[str] = set()

    def get(self, key: str, kind: str, within: dict | None = None, name: str = "", default=None):
        """The field `key` of the file (or of its section `within`, named `name`); `default` if it is not
        there, None if it is of another kind."""
        src = self.d if within is None else within
        if key not in src or src[key] is None:
            return default
        v = src[key]
        ok = {"int": _is_int(v) and abs(v) < 1 << 63, "num": _is_num(v), "str": isinstance(v, str),
              "dict": isinstance(v, dict),
              "strs": isinstance(v, list) and all(isinstance(x, str) for x in v)}[kind]
        if not ok:
            self.odd.add(name or key)
            return None
        return v

    def section(self, key: str) -> dict:
        return self.get(key, "dict") or {}


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v) -> bool:
    return (isinstance(v, float) and math.isfinite(v)) or (_is_int(v) and abs(v) < 1 << 63)


def _alive(pid) -> bool:
    if not _is_int(pid) or not 0 < pid < 1 << 31:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process (the service's)
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rsplit(b")", 1)[-1].split()[0] != b"Z"  # a zombie: killed, not yet reaped
    except (OSError, IndexError):
        return True


def _state(st: Fields) -> tuple[bool, str]:
    """(running, what to say about it)."""
    state = st.get("state", "str") or "?"
    age = _age(st)
    every = st.get("every_s", "num")
    every = every if every is not None and every > 0 else 2.0
    pid = st.get("pid", "int")
    if state == "ended":
        ended = st.get("ended", "str")
        return False, f"ended ({_cut(ended, 200)})" if ended else "ended"
    if not _alive(pid):
        return False, f"not running: its process ({pid if pid is not None else '?'}) is gone; the status is " \
                      f"{_ago(age)} old (killed? `sniffer repair` mends its open segment)"
    if age is not None and age > STALE_AFTER * every:
        return False, f"{state}, but the status has not been written for {_ago(age)} (hung?)"
    return True, state


def _age(st: Fields) -> float | None:
    ns = st.get("updated_ns", "int")
    return (time.time_ns() - ns) / 1e9 if ns is not None else None


def _ago(s: float | None) -> str:
    if s is None:
        return "?"
    s = max(0.0, s)
    for unit, n in (("d", 86_400), ("h", 3_600), ("min", 60)):
        if s >= n:
            return f"{s / n:.1f} {unit}"
    return f"{s:.0f} s"


def _uptime(s) -> str:
    if s is None or not 0 <= s < 1e12:
        return "?"
    d, rest = divmod(int(s), 86_400)
    h, rest = divmod(rest, 3_600)
    m, sec = divmod(rest, 60)
    return (f"{d}d " if d else "") + (f"{h}h " if d or h else "") + f"{m}min {sec}s"


def _size(n) -> str:
    return size_text(n) if n is not None and n >= 0 else "?"


def _count(n) -> str:
    return f"{n:,}" if n is not None else "?"


def lines(d: dict, state: str, st: Fields | None = None) -> list[tuple[str, str]]:
    """The status as (label, text) lines (`st`: the fields as read; a field of the wrong kind is ?)."""
    st = st or Fields(d)
    pid = st.get("pid", "int")
    what = _cut(st.get("command", "str") or st.get("source", "str") or "?", 120)
    out = [("capture", f"{what} (pid {pid if pid is not None else '?'}): {_cut(state)}")]
    if st.get("line", "str"):
        out.append(("line", _cut(st.get("line", "str"))))
    out.append(("started", f"{_cut(st.get('started', 'str') or '?', 40)}, up {_uptime(st.get('uptime_s', 'num'))}; "
                           f"status written {_ago(_age(st))} ago"))
    last = st.section("last_frame")
    if "frames" in d:
        when = ""
        if last:
            wall = st.get("wall", "str", last, "last_frame.wall")
            t = st.get("t", "num", last, "last_frame.t")
            when = f"; last frame at {_cut(wall, 40) if wall else (f'{t} s' if t is not None else '?')}"
            if wall and st.get("updated_ns", "int") is not None:
                when += f" ({_ago(_age_of(wall))} ago)"
        out.append(("frames", f"{_count(st.get('frames', 'int'))} ({_size(st.get('bytes', 'int'))} received){when}"))
    rate = _rates(st)
    if rate:
        out.append(("rate", rate))
    errors = st.get("errors", "dict")
    if errors:
        out.append(("errors", _cut(", ".join(f"{_cut(k, 40)} {v:,}" if _is_int(v) else f"{_cut(k, 40)} {_generic(v)}"
                                             for k, v in errors.items()))))
    units = st.get("units", "dict")
    if units:
        out += _unit_lines(units)
    port = st.section("port")
    pstate = st.get("state", "str", port, "port.state")
    if port and pstate != "ok":
        ports = st.get("ports", "strs", port, "port.ports") or ()
        reason = st.get("reason", "str", port, "port.reason")
        out.append(("port", _cut((f"{', '.join(ports)}: " if len(ports) > 1 else "")
                                 + f"{pstate or '?'} since {st.get('since', 'str', port, 'port.since') or '?'}"
                                 + (f" ({reason})" if reason else ""))))
    seg = st.get("segments", "dict")
    if seg is not None:
        def g(key: str, kind: str, default=None):
            return st.get(key, kind, seg, f"segments.{key}", default)

        free = g("disk_free", "int")
        text = (f"{_count(g('count', 'int', 0))} in {_cut(g('folder', 'str') or '?', 200)} "
                f"({_size(g('bytes', 'int', 0))}"
                f"{f'; {_size(free)} free on its disk' if free is not None else ''}), "
                f"open: {_cut(g('open', 'str') or '-', 200)}; "
                f"rotate {_cut(g('rotate', 'str') or '-', 40)}, keep {_cut(g('keep', 'str') or 'all', 40)}")
        if g("deleted", "int"):
            text += f"; {g('deleted', 'int')} deleted"
        if g("killed", "int"):
            text += f"; {g('killed', 'int')} left open by a killed capture (replayable; `sniffer repair` mends them)"
        out.append(("segments", _cut(text)))
        for err in (g("delete_errors", "strs") or ())[:3]:
            out.append(("", _cut(f"could not delete {err}")))
        keeps = _keeps(st, seg)
        if keeps:
            out.append(("keeps", _cut(keeps)))
    triggers = st.get("triggers", "dict")
    if triggers is not None:
        out += _trigger_lines(st, triggers)
    for key, value in d.items():
        if key not in _KNOWN:
            out.append((_cut(key, 40), _generic(value)))
    return out


def _per_s(st: Fields, n) -> float | None:
    """n bytes over the capture time it covers (a replay's is not its uptime; an older file: its uptime), a second
    (None: not known)."""
    span = st.get("capture_s", "num")
    if span is None or span < 1:
        span = st.get("uptime_s", "num")
    return n / span if n is not None and span is not None and span >= 1 else None


def _rates(st: Fields) -> str:
    """`1.2 kB/s from the line, 9.8 kB/s into the segments (8.2x the line, 847MB a day)`, on average since the
    capture started."""
    line = _per_s(st, st.get("bytes", "int"))
    if line is None:
        return ""
    seg = st.section("segments")
    disk = _per_s(st, st.get("written", "int", seg, "segments.written")) if seg else None
    times = f"{disk / line:.1f}x the line, " if disk and line else ""
    into = f", {_size(round(disk))}/s into the segments ({times}{_size(round(disk * 86_400))} a day)" if disk else ""
    return f"{_size(round(line))}/s from the line{into} (on average over the capture)"


def _keeps(st: Fields, seg: dict) -> str:
    """What --keep holds at the rate the segments grow: `about 3.0 d of capture: 20GB is reached before 14d`; with
    no --keep, how long the disk's free space lasts."""
    disk = _per_s(st, st.get("written", "int", seg, "segments.written"))
    limit = st.get("limits", "dict", seg, "segments.limits")
    if not disk or limit is None:
        return ""
    free = st.get("disk_free", "int", seg, "segments.disk_free")
    fills = f"; the disk's {_size(free)} free fill in about {_ago(free / disk)}" if free is not None else ""
    span = held(disk, limit)
    if span is None:
        return f"everything (no --keep){fills}"
    seconds, which = span
    keep = st.get("keep", "str", seg, "segments.keep") or which
    first = f": {which} comes first" if keep != which else ""
    short = fills if free is not None and free / disk < seconds else ""  # the disk runs out before --keep bites
    return f"about {_ago(seconds)} of capture at {_size(round(disk))}/s (--keep {keep}{first}){short}"


_TRIGGER_COUNTS = (("windows", "window{} written"), ("open", "open now"),
                   ("suppressed", "match{es} fired nothing (the rule not quiet for --post since it fired)"),
                   ("failed_windows", "window{} could not be written"))


_TRIGGER_KNOWN = {"fired", "ring_bytes", "last", "on_trigger", "window_bytes", "window_line_bytes",
                  *(key for key, _ in _TRIGGER_COUNTS)}


def _times(n, what: str) -> str:
    """`1 window written`, `2 windows written` (`{}`: s, `{es}`: es, when n is not 1)."""
    many = n != 1
    return f"{_count(n)} " + what.replace("{es}", "es" if many else "").replace("{}", "s" if many else "")


def _trigger_lines(st: Fields, t: dict) -> list[tuple[str, str]]:
    """The `triggers` section in words: what fired, the windows, the last event, the --on-trigger command."""
    def g(key: str, kind: str, within: dict | None = None, name: str = ""):
        return st.get(key, kind, t if within is None else within, name or f"triggers.{key}")

    words = [f"fired {_times(g('fired', 'int'), 'time{}')}"]
    words += [_times(v, text) for key, text in _TRIGGER_COUNTS if (v := g(key, "int")) or (key == "windows" and v == 0)]
    size, line = g("window_bytes", "int"), g("window_line_bytes", "int")
    if size and g("windows", "int"):  # `3 windows written (1.2MB, 4.1x the line's bytes they hold)`
        words[1] += f" ({_size(size)}" + (f", {size / line:.1f}x the line's bytes they hold)" if line else ")")
    ring = g("ring_bytes", "int")
    if ring is not None:
        words.append(f"{_size(ring)} held for --pre")
    more = {k: v for k, v in t.items() if k not in _TRIGGER_KNOWN}
    if more:  # what a later sniffer's trigger sink adds: as any section this command does not know
        words.append(_generic(more))
    out = [("triggers", _cut(", ".join(words)))]
    last = g("last", "dict")
    if last:
        def lg(key: str, kind: str):
            return st.get(key, kind, last, f"triggers.last.{key}")

        t_rel = lg("t", "num")
        when = lg("time", "str") or (f"{t_rel:.3f} s into the capture" if t_rel is not None else "?")
        frame = lg("frame", "int")
        text = f"last: {_cut(lg('rule', 'str') or '?', 80)!r} at {_cut(when, 40)}"
        text += f", frame #{frame}" if frame is not None else ""
        summary = lg("summary", "str")
        text += f": {_cut(summary, 100)}" if summary else ""
        window = lg("window", "str")
        out.append(("", _cut(text + (f" -> {window}" if window else ""))))
    cmd = g("on_trigger", "dict")
    if cmd:
        def cg(key: str):
            return st.get(key, "int", cmd, f"triggers.on_trigger.{key}")

        text = f"--on-trigger ran {_times(cg('ran'), 'time{}')}, {_count(cg('failed'))} failed"
        text += "".join(f", {_count(v)} {what}" for what, v in (("timed out", cg("timed_out")),
                                                                 ("dropped (too many waiting)", cg("dropped"))) if v)
        err = st.get("last_error", "str", cmd, "triggers.on_trigger.last_error")
        out.append(("", _cut(text + (f"; last error: {err}" if err else ""))))
    return out


def _unit_lines(units: dict) -> list[tuple[str, str]]:
    """A line per unit: its figures (sniffer.analysis.unitfigures), the latency's to the microsecond."""
    def count(u: dict, key: str) -> str:
        v = u.get(key)
        return f"{v:,}" if _is_int(v) else "?"

    def ms(u: dict, key: str) -> str:
        v = u.get(key)
        return f"{v:.3f}" if isinstance(v, (int, float)) and not isinstance(v, bool) else "?"

    out = []
    for name, u in list(units.items())[:UNITS_SHOWN]:
        if not isinstance(u, dict):
            continue
        counts = [f"req {count(u, 'requests')}", f"rsp {count(u, 'responses')}", f"CRC err {count(u, 'crc_errors')}",
                  f"exc {count(u, 'exceptions')}", f"timeouts {count(u, 'timeouts')}",
                  f"retries {count(u, 'retries')}"]
        counts += [f"{label} {count(u, key)}" for key, label in (("faults", "faults"), ("alarms", "alarms"),
                                                                  ("late", "late"),
                                                                  ("unanswered_at_end", "unanswered at end"))
                   if u.get(key)]
        if u.get("lat_n"):
            approx = "" if u.get("lat_exact", True) is True else " (within 0.1 %)"
            counts.append(f"latency median {ms(u, 'lat_median')} p95 {ms(u, 'lat_p95')} max {ms(u, 'lat_max')} ms"
                          f"{approx}")
        ghost = " (CRC-bad frames only: a damaged address?)" if u.get("ghost") is True else ""
        out.append((_cut(f"unit {name}", 40), _cut(", ".join(counts) + ghost)))
    if len(units) > UNITS_SHOWN:
        out.append(("", f"and {len(units) - UNITS_SHOWN} more units (--json)"))
    return out


def _age_of(iso_text: str) -> float | None:
    try:
        return time.time() - calendar.timegm(time.strptime(iso_text, "%Y-%m-%dT%H:%M:%SZ"))
    except (TypeError, ValueError, OverflowError):
        return None


def _generic(value, prefix: str = "", depth: int = 0) -> str:
    """A section this command does not know, on one line: `a 1, b.c 2, d [x, y]` (two levels deep, at
    most GENERIC_WIDTH characters: `--json` has it all)."""
    if not isinstance(value, dict):
        return _cut(value if isinstance(value, str) else _json(value))
    parts = []
    for k, v in list(value.items())[:50]:
        if isinstance(v, dict):
            parts.append(_generic(v, f"{prefix}{k}.", depth + 1) if depth < 1 else f"{prefix}{k} {{...}}")
        elif isinstance(v, (list, tuple)) and len(_json(v)) > 60:
            parts.append(f"{prefix}{k} [{len(v)}]")
        else:
            parts.append(f"{prefix}{k} {_cut(v if isinstance(v, (str, int, float)) else _json(v), 80)}")
    text = ", ".join(p for p in parts if p)
    return text if depth else _cut(text, GENERIC_WIDTH)


def _json(value) -> str:
    try:
        return json.dumps(value)
    except (RecursionError, ValueError):
        return "[...]" if isinstance(value, list) else "?"


def _cut(text, width: int = GENERIC_WIDTH) -> str:
    text = " ".join(str(text)[: width * 4].split())
    return text if len(text) <= width else text[: width - 3] + "..."
