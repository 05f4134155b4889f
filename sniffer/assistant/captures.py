"""A capture file as an assistant reads it: its summary, units, findings and the report's figures (one pass,
kept while the file is unchanged), its frames by the filter language, a register's history.

Every answer is decoded by the same capture session as `sniffer replay`; nothing is written anywhere.
"""

from __future__ import annotations

import os
import threading

from sniffer.assistant.bounds import ANSWER_BYTES, fit, scrub
from sniffer.decoding import decode_file
from sniffer.formats.records import frame_record

MAX_FRAMES = 200  # frames of one page
MAX_SAMPLES = 1_000  # changes of one register's history
_REPORT_KEYS = ("captures", "totals", "units", "polls", "registers", "timeline")


class Analysis:
    """The one-pass figures of a capture (sniffer.report's Collector, its diagnosis included)."""

    def __init__(self, path: str) -> None:
        from sniffer.report import Collector

        session = decode_file(path)
        collector = Collector(compare=False)
        collector.begin(path, session)
        for f in session:
            collector.frame(f)
        collector.end(session)
        self.info = session.info
        self.frames = session.frames_out
        self.damage = list(session.damage)
        self.data = collector.to_data()


_cache: dict[str, tuple[tuple, Analysis]] = {}
_lock = threading.Lock()


def _stamp(path: str) -> tuple:
    """What changes when a capture does (a rotated capture's folder: its newest segment)."""
    st = os.stat(path)
    if os.path.isdir(path):
        newest = max((e.stat().st_mtime_ns for e in os.scandir(path) if e.is_file()), default=0)
        return (st.st_mtime_ns, newest)
    return (st.st_mtime_ns, st.st_size)


def analysis(path: str) -> Analysis:
    with _lock:
        stamp = _stamp(path)
        got = _cache.get(path)
        if got is None or got[0] != stamp:
            got = _cache[path] = (stamp, Analysis(path))
        return got[1]


def summary(path: str) -> dict:
    """The capture's line, span, frame and byte counts, problem codes and one row per unit."""
    a = analysis(path)
    info = a.info
    d = a.data
    findings = d["findings"]
    return scrub({
        "capture": path, "source": info.source, "port": info.port, "protocol": info.protocol,
        "line": f"{info.baud} {info.databits}{info.parity}{info.stopbits}", "time_source": info.time_source,
        "devices": {str(u): m for u, m in (info.devices or {}).items()},
        "duration_s": round(d["axis"]["end_s"], 6), "frames": d["totals"]["frames"], "bytes": d["totals"]["bytes"],
        "codes": d["totals"]["codes"], "damage": a.damage,
        "findings": {s: sum(1 for f in findings if f["severity"] == s) for s in ("error", "warning", "info")},
        "units": d["units"],
    })


def findings(path: str, severity: str | None = None, limit: int = 50) -> dict:
    """`sniffer diagnose`'s findings, most severe first (or only those of `severity`)."""
    found = analysis(path).data["findings"]
    if severity:
        found = [f for f in found if f["severity"] == severity]
    kept, cut = fit(scrub(found[:limit]), ANSWER_BYTES)
    return {"capture": path, "findings": kept, "total": len(found), "left_out": len(found) - len(kept),
            "truncated": cut or len(found) > limit}


def report_figures(path: str, limit: int = 100) -> dict:
    """The report's tables (units, poll types, changed registers, timeline events) without its plot arrays."""
    d = analysis(path).data
    out = {}
    for key in _REPORT_KEYS:
        v = d[key]
        if isinstance(v, dict) and "rows" in v:
            v = {**v, "rows": v["rows"][:limit], "rows_total": len(v["rows"])}
        elif isinstance(v, dict) and "events" in v:
            v = {**v, "events": v["events"][:limit], "events_total": len(v["events"])}
        out[key] = v
    out["latency"] = {"units_timed": d["latency"]["units_timed"]}
    out["turnaround"] = {k: d["turnaround"][k] for k in ("time_sources", "limits", "t15", "t35", "below15", "below35")}
    out = scrub(out)
    while out and len(str(out)) > ANSWER_BYTES:  # the biggest table gives way first
        biggest = max(("polls", "registers", "timeline"), key=lambda k: len(str(out.get(k))))
        inner = out[biggest]
        rows = inner.get("rows") or inner.get("events")
        if not rows:
            break
        del rows[len(rows) // 2:]
    return {"capture": path, **out}


def frames(path: str, text: str = "", offset: int = 0, limit: int = 50) -> dict:
    """A page of the frames that pass filter `text`: from match `offset`, at most `limit` and ANSWER_BYTES;
    `next_offset` continues (None at the end)."""
    from sniffer.filterlang import Context, Query

    query = Query(text or None)  # FilterError (a ValueError): the column and what is wrong
    session = decode_file(path)
    ctx = Context(session.info.t0_ns)
    page, seen, more = [], 0, False
    for f in session:
        if query and not query.matches(f, ctx):
            continue
        if seen >= offset:
            if len(page) == limit:
                more = True
                break
            page.append(scrub(frame_record(f, session.info.t0_ns)))
        seen += 1
    kept, cut = fit(page, ANSWER_BYTES - 300)
    nxt = offset + len(kept) if (more or cut) else None
    return {"capture": path, "filter": str(query), "offset": offset, "frames": kept, "next_offset": nxt,
            "cut_by_size": cut}


def _register_test(register: str):
    """A test of a decoded point for `register`: an address (9508, 2524H, 0x2524), a parameter id or a name."""
    r = register.strip()
    address = None
    try:
        if r.lower().endswith("h"):
            address = int(r[:-1], 16)
        else:
            address = int(r, 0)
    except ValueError:
        pass
    low = r.lower()
    if address is not None:
        return lambda p: p.get("address") == address
    return lambda p: low in ((p.get("id") or "").lower(), (p.get("name") or "").lower())


def history(path: str, unit: int, register: str, limit: int = 200) -> dict:
    """A register's decoded values over the capture for one unit: each change (time, value, text, frame), the
    first and last sample, and how many samples there were."""
    test = _register_test(register)
    session = decode_file(path)
    t0 = session.info.t0_ns
    changes, samples, last, name, first = [], 0, object(), None, None
    sample = None
    for f in session:
        if f.unit != unit or not f.points:
            continue
        for p in f.points:
            if not test(p):
                continue
            samples += 1
            name = name or {k: p.get(k) for k in ("name", "id", "address", "unit")}
            value = p.get("value")
            sample = {"t": round((f.t_ns - t0) / 1e9, 6), "value": value, "frame": f.index}
            if p.get("text"):
                sample["text"] = p["text"]
            first = first or sample
            if value != last and len(changes) < limit:
                changes.append(sample)
            last = value
    if not samples:
        raise ValueError(f"no decoded value of {register[:60]!r} for unit {unit} in {path} (name it by address "
                         f"such as 2524H, by parameter id, or by the name the frames show)")
    kept, cut = fit(scrub(changes), ANSWER_BYTES - 1_000)
    return {"capture": path, "unit": unit, "register": scrub(name), "samples": samples, "first": scrub(first),
            "last": scrub(sample), "changes": kept, "truncated": cut or len(changes) >= limit}
