"""`sniffer status [FOLDER|FILE]`: how an unattended capture is doing, from its status file (sniffer.capture.status).

Exit status: 0 the capture is running (its status is fresh), 1 it ended, or
its status is stale (the process is gone, or has not written for a while),
2 no status file there.  Sections a sink contributed that this command does
not know (e.g. `triggers`) are shown generically, one line each.
"""

from __future__ import annotations

import calendar
import json
import os
import sys
import time

from sniffer.formats.outputs import shown
from sniffer.formats.mcap.segments import STATUS_NAME, read_json, size_text
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_FAILED, EXIT_OK, UsageError

_KNOWN = {"format", "state", "pid", "command", "source", "line", "started", "updated", "updated_ns", "every_s",
          "uptime_s", "frames", "bytes", "errors", "last_frame", "port", "segments", "ended", "units"}
STALE_AFTER = 3  # status intervals without a write: the capture is not running
GENERIC_WIDTH = 300
UNITS_SHOWN = 32  # unit lines (`--json` has them all)


def cmd_status(spec: CaptureSpec, args) -> int:
    path = args.path
    if os.path.isdir(path):
        path = os.path.join(path, STATUS_NAME)
    d = read_json(path)
    if d is None:
        why = "no such file" if not os.path.exists(path) else "not a status file (JSON object)"
        raise UsageError(f"{shown(path)}: {why} (a capture writes it with --rotate or --status FILE)")
    if args.json:
        json.dump(d, sys.stdout, indent=1)
        print()
        return EXIT_OK
    running, state = _state(d)
    for label, text in lines(d, state):
        print(f"{label:<9} {text}")  # a long label (a unit of a link) still gets its space
    return EXIT_OK if running else EXIT_FAILED


def _alive(pid) -> bool:
    if not isinstance(pid, int) or pid <= 0:
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


def _state(d: dict) -> tuple[bool, str]:
    """(running, what to say about it)."""
    state = str(d.get("state", "?"))
    age = _age(d)
    every = float(d.get("every_s") or 2.0)
    if state == "ended":
        return False, f"ended ({d.get('ended', '')})" if d.get("ended") else "ended"
    if not _alive(d.get("pid")):
        return False, f"not running: its process ({d.get('pid')}) is gone; the status is {_ago(age)} old " \
                      f"(killed? `sniffer repair` mends its open segment)"
    if age is not None and age > STALE_AFTER * every:
        return False, f"{state}, but the status has not been written for {_ago(age)} (hung?)"
    return True, state


def _age(d: dict) -> float | None:
    ns = d.get("updated_ns")
    return (time.time_ns() - ns) / 1e9 if isinstance(ns, int) else None


def _ago(s: float | None) -> str:
    if s is None:
        return "?"
    s = max(0.0, s)
    for unit, n in (("d", 86_400), ("h", 3_600), ("min", 60)):
        if s >= n:
            return f"{s / n:.1f} {unit}"
    return f"{s:.0f} s"


def _uptime(s) -> str:
    if not isinstance(s, (int, float)):
        return "?"
    d, rest = divmod(int(s), 86_400)
    h, rest = divmod(rest, 3_600)
    m, sec = divmod(rest, 60)
    return (f"{d}d " if d else "") + (f"{h}h " if d or h else "") + f"{m}min {sec}s"


def lines(d: dict, state: str) -> list[tuple[str, str]]:
    """The status as (label, text) lines."""
    out = [("capture", f"{d.get('command') or d.get('source') or '?'} (pid {d.get('pid')}): {state}")]
    if d.get("line"):
        out.append(("line", str(d["line"])))
    out.append(("started", f"{d.get('started') or '?'}, up {_uptime(d.get('uptime_s'))}; "
                           f"status written {_ago(_age(d))} ago"))
    last = d.get("last_frame") or {}
    if "frames" in d:
        when = ""
        if last:
            when = f"; last frame at {last.get('wall') or str(last.get('t')) + ' s'}"
            if last.get("wall") and isinstance(d.get("updated_ns"), int):
                when += f" ({_ago(_age_of(last['wall']))} ago)"
        out.append(("frames", f"{d['frames']:,} ({size_text(int(d.get('bytes') or 0))} received){when}"))
    errors = d.get("errors")
    if isinstance(errors, dict):
        out.append(("errors", ", ".join(f"{k} {v:,}" if isinstance(v, int) else f"{k} {v}"
                                        for k, v in errors.items())))
    units = d.get("units")
    if isinstance(units, dict):
        out += _unit_lines(units)
    port = d.get("port")
    if isinstance(port, dict) and port.get("state") not in (None, "ok"):
        ports = port.get("ports") or ()
        out.append(("port", (f"{', '.join(ports)}: " if len(ports) > 1 else "")
                    + f"{port.get('state')} since {port.get('since', '?')}"
                    + (f" ({port['reason']})" if port.get("reason") else "")))
    seg = d.get("segments")
    if isinstance(seg, dict):
        free = f"; {size_text(seg['disk_free'])} free on its disk" if isinstance(seg.get("disk_free"), int) else ""
        text = (f"{seg.get('count', 0)} in {seg.get('folder', '?')} ({size_text(int(seg.get('bytes') or 0))}{free}), "
                f"open: {seg.get('open') or '-'}; rotate {seg.get('rotate') or '-'}, keep {seg.get('keep') or 'all'}")
        if seg.get("deleted"):
            text += f"; {seg['deleted']} deleted"
        if seg.get("killed"):
            text += f"; {seg['killed']} left open by a killed capture (replayable; `sniffer repair` mends them)"
        out.append(("segments", text))
        for err in seg.get("delete_errors") or ():
            out.append(("", f"could not delete {err}"))
    for key, value in d.items():
        if key not in _KNOWN:
            out.append((key, _generic(value)))
    return out


def _unit_lines(units: dict) -> list[tuple[str, str]]:
    """A line per unit: its figures (sniffer.analysis.unitfigures), the latency's to the microsecond."""
    out = []
    for name, u in list(units.items())[:UNITS_SHOWN]:
        if not isinstance(u, dict):
            continue
        counts = [f"req {u.get('requests')}", f"rsp {u.get('responses')}", f"CRC err {u.get('crc_errors')}",
                  f"exc {u.get('exceptions')}", f"timeouts {u.get('timeouts')}", f"retries {u.get('retries')}"]
        counts += [f"{label} {u[key]}" for key, label in (("faults", "faults"), ("alarms", "alarms"), ("late", "late"),
                                                          ("unanswered_at_end", "unanswered at end")) if u.get(key)]
        if u.get("lat_n"):
            approx = "" if u.get("lat_exact", True) else " (within 0.1 %)"
            counts.append(f"latency median {u.get('lat_median'):.3f} p95 {u.get('lat_p95'):.3f} "
                          f"max {u.get('lat_max'):.3f} ms{approx}")
        ghost = " (CRC-bad frames only: a damaged address?)" if u.get("ghost") else ""
        out.append((f"unit {name}", ", ".join(counts) + ghost))
    if len(units) > UNITS_SHOWN:
        out.append(("", f"and {len(units) - UNITS_SHOWN} more units (--json)"))
    return out


def _age_of(iso_text: str) -> float | None:
    try:
        return time.time() - calendar.timegm(time.strptime(iso_text, "%Y-%m-%dT%H:%M:%SZ"))
    except (TypeError, ValueError):
        return None


def _generic(value, prefix: str = "", depth: int = 0) -> str:
    """A section this command does not know, on one line: `a 1, b.c 2, d [x, y]` (two levels deep, at
    most GENERIC_WIDTH characters: `--json` has it all)."""
    if not isinstance(value, dict):
        return _cut(value if isinstance(value, str) else json.dumps(value))
    parts = []
    for k, v in value.items():
        if isinstance(v, dict):
            parts.append(_generic(v, f"{prefix}{k}.", depth + 1) if depth < 1 else f"{prefix}{k} {{...}}")
        elif isinstance(v, (list, tuple)) and len(json.dumps(v)) > 60:
            parts.append(f"{prefix}{k} [{len(v)}]")
        else:
            parts.append(f"{prefix}{k} {_cut(v if isinstance(v, (str, int, float)) else json.dumps(v), 80)}")
    text = ", ".join(p for p in parts if p)
    return text if depth else _cut(text, GENERIC_WIDTH)


def _cut(text, width: int = GENERIC_WIDTH) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= width else text[: width - 3] + "..."
