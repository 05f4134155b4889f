"""The report as one HTML file: tables written here, plots drawn in the browser by report.js with uPlot.

Everything is inline (uPlot's script and style, ours, the data as JSON), so the file
opens offline from anywhere and can be mailed as it is.  The data block is the
collector's `to_data()` (plus the comparison, if any); the tables need no script.
"""

from __future__ import annotations

import datetime as _dt
import json
from html import escape
from importlib import resources

from sniffer import __version__

SECTIONS = (("verdicts", "Verdicts"),
            ("captures", "Captures"), ("units", "Units"), ("latency", "Latency"), ("polls", "Poll cycles"),
            ("line", "Line"), ("errors", "Errors"), ("timing", "Turnaround"), ("registers", "Registers"),
            ("timeline", "Writes and faults"), ("compare", "Compare"))
TIME_SOURCES = {
    "byte": "timestamps per byte (a logic analyzer or the simulator): turnaround measured",
    "read": "timestamps per USB read: turnaround estimated from the read times and the baud rate (a response in "
            "the same read as its request has none)",
    "net": "timestamps per network read (a gateway's rfc2217:// or socket:// line): after the gateway's packing "
           "and the network, so a turnaround is estimated as for a USB read and missing more often",
    "none": "no timestamps (frames typed in): no turnaround",
}


def _asset(name: str) -> str:
    return resources.files(__package__).joinpath(name).read_text(encoding="utf-8")


def _script(text: str) -> str:
    return text.replace("</script", "<\\/script")


def _e(v) -> str:
    return "–" if v is None or v == "" else escape(str(v))


def _n(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:,.3f}".rstrip("0").rstrip(".")
    return f"{v:,}" if isinstance(v, int) else escape(str(v))


def _table(head: list[str], rows: list[list[str]], cls: str = "") -> str:
    th = "".join(f"<th>{escape(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="data {cls}"><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>'


def _plot(pid: str, title: str, note: str = "") -> str:
    n = f'<p class="note">{note}</p>' if note else ""
    return (f'<figure class="plot" id="{pid}" data-title="{escape(title)}">'
            f"<figcaption>{escape(title)}</figcaption>{n}</figure>")


def _section(sid: str, title: str, body: str) -> str:
    return f'<section id="{sid}"><h2>{escape(title)}</h2>{body}</section>'


def render(data: dict, title: str) -> str:
    """The whole page."""
    generated = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    data = dict(data, title=title, generated=generated, version=__version__)
    parts = [_glance(data), _verdicts(data), _captures(data), _units(data), _latency(data), _polls(data), _line(data),
             _errors(data), _timing(data), _registers(data), _timeline(data)]
    if data.get("compare") is not None:
        parts.append(_compare(data["compare"]))
    nav = "".join(f'<a href="#{sid}">{escape(t)}</a>' for sid, t in SECTIONS
                  if sid != "compare" or data.get("compare") is not None)
    blob = json.dumps(data, separators=(",", ":"), allow_nan=False, default=str).replace("</", "<\\/")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
        f"<title>{escape(title)}</title>"
        f"<style>{_asset('vendor/uPlot.min.css')}</style><style>{_asset('report.css')}</style></head><body>"
        f"<header><h1>{escape(title)}</h1><p class=\"sub\">written {escape(generated)} by sniffer {escape(__version__)}"
        f" · {len(data['captures'])} capture(s)</p><nav>{nav}</nav>"
        "<p class=\"help\">Plots over time: drag to zoom in, mouse wheel to zoom, Shift+drag (or the middle button) "
        "to pan, double-click to see everything. <label><input type=\"checkbox\" id=\"sync\" checked> zoom all time "
        "plots together</label></p></header><main>"
        + "".join(parts)
        + "</main><footer>Plots drawn with uPlot (MIT licence, © Leon Sorokin), inline in this file.</footer>"
        f"<script type=\"application/json\" id=\"report-data\">{blob}</script>"
        f"<script>{_script(_asset('vendor/uPlot.iife.min.js'))}</script>"
        f"<script>{_script(_asset('report.js'))}</script></body></html>\n"
    )


def _glance(d: dict) -> str:
    units, t = d["units"], d["totals"]
    tl = d["timeline"]["counts"]
    cards = [("frames", _n(t["frames"])), ("duration", _dur(d["axis"]["end_s"])), ("units", _n(len(units))),
             ("CRC errors", _n(sum(u["crc_errors"] for u in units))),
             ("exceptions", _n(sum(u["exceptions"] for u in units))),
             ("timeouts", _n(sum(u["timeouts"] for u in units))), ("retries", _n(sum(u["retries"] for u in units))),
             ("fault episodes", _n(tl.get("fault", 0))), ("writes", _n(tl.get("write", 0)))]
    bad = {"CRC errors", "exceptions", "timeouts", "retries", "fault episodes"}
    html = "".join(f'<div class="card{" bad" if k in bad and v not in ("0", "–") else ""}"><b>{v}</b>{escape(k)}</div>'
                   for k, v in cards)
    return f'<section id="glance" class="cards">{html}</section>'


def _verdicts(d: dict) -> str:
    """What is wrong on the line, why, and what to do (sniffer diagnose's findings), most severe first."""
    findings = d.get("findings") or []
    if not findings:
        return _section("verdicts", "Verdicts", "<p>No finding: nothing on the line looks wrong.</p>")
    counts = {s: sum(1 for f in findings if f["severity"] == s) for s in ("error", "warning", "info")}
    head = (f'<p class="note">{counts["error"]} error(s), {counts["warning"]} warning(s), {counts["info"]} note(s), '
            f"most severe first (the same as <code>sniffer diagnose</code>; docs/diagnose.md says what each "
            f"means).</p>")
    items = []
    for f in findings:
        where = ("the line" if f["unit"] is None else f"unit {f['unit']}")
        if f.get("link"):
            where = f"{f['link']}: {where}"
        span = "" if f["t_start"] is None else f" · {_n(f['t_start'])}-{_n(f['t_end'])} s"
        ev = ", ".join(f"{escape(k.replace('_', ' '))} <b>{_ev(v)}</b>" for k, v in f["evidence"].items())
        stat = ('<p class="stat">statistic: '
                + ", ".join(f"{escape(str(k))} {_ev(v)}" for k, v in f["statistic"].items()) + "</p>"
                if f.get("statistic") else "")
        frames = " ".join(f"#{i}" for i in f["frames"])
        when = _when(f)
        items.append(
            f'<div class="finding sev-{escape(f["severity"])}"><p class="what">'
            f'<span class="sev">{escape(f["severity"])}</span> <b>{escape(f["kind"])}</b> · {escape(where)}{span}</p>'
            f'<p>{escape(f["text"])}</p>'
            + (f'<p class="when">when: {escape(when)}</p>' if when else "")
            + f'<p class="evidence">{ev}</p>{stat}'
            + (f'<p class="frames">frames to look at: {escape(frames)}</p>' if frames else "")
            + f'<p class="todo">what to do: {escape(f["action"])}</p></div>')
    return _section("verdicts", "Verdicts", head + "".join(items))


def _ev(v) -> str:
    from sniffer.diagnose.finding import fmt_value

    if isinstance(v, float):
        return escape(f"{v:.3g}" if v and (abs(v) < 0.001 or abs(v) >= 1e6) else _n(v))
    if isinstance(v, (dict, list, tuple)) or v is None or isinstance(v, bool):
        return escape(fmt_value(v))  # in words: no Python spelling of a table, a list or None
    return _n(v)


def _when(f: dict) -> str:
    """A finding's episodes in words (from its JSON form)."""
    from sniffer.diagnose.episodes import Episode, words

    eps = [Episode(e["from_s"], e["to_s"], e["count"], e.get("what", "")) for e in f.get("episodes") or ()]
    return words(eps, f.get("episode_count") or len(eps))


def _dur(s: float) -> str:
    s = max(s, 0.0)
    if s < 120:
        return f"{s:.1f} s"
    h, rest = divmod(int(round(s)), 3600)
    m, sec = divmod(rest, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


def _captures(d: dict) -> str:
    rows = []
    for i, c in enumerate(d["captures"], 1):
        problems = "; ".join([*(c.get("damage") or []), *([c["error"]] if c.get("error") else [])])
        ll = c.get("low_latency") or {}
        note = f'<br><span class="warn">{_e(c["note"])}</span>' if c.get("note") else ""
        rows.append([
            f"{i}", f'<span class="path" title="{_e(c["path"])}">{_e(c["label"])}</span>{note}',
            _e(c.get("start_wall") or "unknown (no wall clock)"), _dur(c.get("duration_s") or 0),
            _line_cell(c), _devices_cell(c),
            _e(_settings(c)),
            _e(c["time_source"]), _ev(ll) if ll else _e(None),
            _n(c.get("frames")), _n(c.get("bytes")), _n(c.get("noise_bytes")),
            _e(c.get("source")) + (f" {_e(c['port'])}" if c.get("port") else ""), _e(c.get("recorded_by")),
            _n(c.get("size")), f'<code>{_e((c.get("sha256") or "")[:16])}</code>',
            f'<span class="bad">{_e(problems)}</span>' if problems else "none",
        ])
    head = ["#", "file", "start (UTC)", "duration", "line", "devices", "timeouts, maps", "time source", "low latency",
            "frames", "bytes", "noise bytes", "recorded from", "by sniffer", "file size", "SHA-256", "damage"]
    return _section("captures", "Captures: settings and provenance", _table(head, rows, "wide"))


def _line_cell(c: dict) -> str:
    if c.get("links"):  # several links: each its own line
        return "<br>".join(f"{_e(x['name'])}: {_e(x['line'])} {_e(x['protocol'])}" for x in c["links"])
    return _e(c["line"]) + " " + _e(c["protocol"])


def _devices_cell(c: dict) -> str:
    def text(devices: dict) -> str:
        return ", ".join(f"{u}={m}" for u, m in devices.items())

    if c.get("links"):
        return "<br>".join(f"{_e(x['name'])}: {_e(text(x['devices']))}" for x in c["links"])
    return _e(text(c["devices"]))


def _settings(c: dict) -> str:
    """The response timeouts and the files the decoding used."""
    parts = [f"timeout {c['timeout_ms']:g} ms"]
    parts += [f"u{u} {ms:g} ms" for u, ms in c["unit_timeouts"].items()]
    if c.get("bus_file"):
        parts.append(f"bus file {c['bus_file']}")
    parts += [f"model file {m}" for m in c["model_files"]]
    return "; ".join(parts)


def _units(d: dict) -> str:
    rows = [[f"{u['unit']}", _e(u["model"]) + (' <span class="warn">CRC-bad frames only</span>' if u["ghost"] else ""),
             _n(u["requests"]), _n(u["responses"]), _n(u["crc_errors"]), _n(u["exceptions"]), _n(u["timeouts"]),
             _n(u["retries"]), _n(u["late"]), _n(u["unanswered_at_end"]), _n(u["faults"]), _n(u["alarms"]),
             _n(u["writes"]), _n(u["lat_min"]), _n(u["lat_median"]), _n(u["lat_p95"]), _n(u["lat_p99"]),
             _n(u["lat_max"]), _n(u["unmeasured"]), _n(u["polls_per_s"]), _n(u["first_s"]), _n(u["last_s"])]
            for u in d["units"]]
    head = ["unit", "model", "requests", "responses", "CRC err", "exceptions", "timeouts", "retries", "late",
            "unanswered at end", "fault reports", "alarm reports", "writes", "lat min ms", "lat median", "lat p95",
            "lat p99", "lat max", "answered, no latency", "polls/s (mean)", "first seen s", "last seen s"]
    approx = [u["unit"] for u in d["units"] if not u["lat_exact"]]
    note = ('<p class="note">A timeout is a request that got no response (not a late one, not one the capture '
            'ended on); latency runs from the end of a request to the start of its response; quantiles by the '
            'nearest rank' + (f", within 0.1 % for unit(s) {_e(', '.join(approx))}" if approx else ", exact")
            + ' (the sniffer\'s docs/figures.md).</p>')
    return _section("units", "Units", _table(head, rows, "wide") + note if rows else "<p>No unit on the line.</p>")


def _latency(d: dict) -> str:
    lat = d["latency"]
    if not lat["bins"]:
        return _section("latency", "Response latency", "<p>No response with a measured latency.</p>")
    shown = len(lat["bins"])
    note = f"the {shown} units with the most answers of {lat['units_timed']}" if lat["units_timed"] > shown else ""
    return _section("latency", "Response latency", _plot("plot-lat-hist", "Latency histogram per unit (ms, log scale)",
                                                         note)
                    + _plot("plot-lat-time", "Latency over time per unit (ms)",
                            "each unit's responses, thinned to the first, fastest, slowest and last of each stretch"))


def _polls(d: dict) -> str:
    p = d["polls"]
    rows = [[_e(r["type"]), _n(r["count"]), _n(r["period_ms"]), _n(r["p5_ms"]), _n(r["p95_ms"]), _n(r["jitter_ms"]),
             _n(r["std_ms"]), _n(r["min_ms"]), _n(r["max_ms"])] for r in p["rows"]]
    note = f"<p class=\"note\">{p['untracked']:,} requests of further request types not timed.</p>" \
        if p["untracked"] else ""
    head = ["request type", "requests", "period ms (median)", "p5", "p95", "jitter (p95-p5)", "std dev", "min", "max"]
    plot = _plot("plot-polls", "Poll period per request type over time (ms between two requests of the type)",
                 f"the {len(p['series'])} most frequent types") if p["series"] else ""
    return _section("polls", "Poll cycles", plot + (_table(head, rows) if rows else "<p>No requests.</p>") + note)


def _line(d: dict) -> str:
    if not d["buckets"]["x"]:
        return _section("line", "Line utilisation", "<p>No frames.</p>")
    return _section("line", "Line utilisation", _plot(
        "plot-util", "Line busy (% of the time a character is on the wire) and frames per second",
        f"per bucket of {d['buckets']['width_s']:g} s; a frame's wire time is its characters at the line's baud"))


def _errors(d: dict) -> str:
    codes = d["totals"]["codes"]
    rows = [[f"<code>{_e(k)}</code>", _n(v)] for k, v in codes.items()]
    plot = _plot("plot-errors", "Problems per bucket", f"per bucket of {d['buckets']['width_s']:g} s") \
        if d["buckets"]["x"] else ""
    return _section("errors", "CRC errors, exceptions, timeouts and retries over time", plot
        + "<h3>Annotations in the capture(s)</h3>" + (_table(["code", "frames"], rows) if rows else "<p>None.</p>"))


def _timing(d: dict) -> str:
    t = d["turnaround"]
    how = "".join(f"<li><b>{_e(s)}</b>: {_e(TIME_SOURCES.get(s, s))}</li>" for s in t["capture_time_sources"])
    measured = ", ".join(f"{n:,} by {s}" for s, n in t["time_sources"].items()) or "none"
    limits = " and ".join(f"t1.5 = {a:g}, t3.5 = {b:g}" for a, b in t["limits"])
    facts = (f"<ul class=\"facts\"><li>the line's limits in character times: {escape(limits)} (3.5 and 1.5 "
             f"characters up to 19200 baud, 1.75 ms and 750 µs above: Modbus serial line 2.5.1.1)</li>"
             f"<li>responses under t3.5 after their request: <b>{t['below35']:,}</b>, of them under t1.5: "
             f"<b>{t['below15']:,}</b></li>"
             f"<li>frames flagged <code>modbus.timing.t35</code> (started under t3.5 after the frame "
             f"before): <b>{t['t35']:,}</b>; <code>modbus.timing.t15</code> (a gap over t1.5 inside a "
             f"frame): <b>{t['t15']:,}</b></li><li>turnarounds measured: {measured}</li></ul>")
    plot = _plot("plot-turn", "Turnaround in character times (request end to response start), per unit",
                 "dashed: t1.5 and t3.5") if t["bins"] else "<p>No response with a measured turnaround.</p>"
    over_time = _plot("plot-violations", "t1.5 / t3.5 violations per bucket") if d["buckets"]["x"] else ""
    return _section("timing", "Turnaround and t1.5 / t3.5", f"<p>How the timestamps were taken:</p><ul>{how}</ul>"
                    + facts + plot + over_time)


def _registers(d: dict) -> str:
    r = d["registers"]
    if not r["rows"]:
        return _section("registers", "Register trends",
                        f"<p>No decoded value changed ({r['registers']:,} registers seen).</p>")
    plots = "".join(_plot(f"plot-reg-{i}", f"unit {p['unit']}" + (f" · {p['eng_unit']}" if p["eng_unit"] else ""),
                          f"and {p['more']} more in the table" if p["more"] else "")
                    for i, p in enumerate(r["plots"]))
    more = f"<p class=\"note\">{r['groups'] - len(r['plots'])} more groups in the table only.</p>" \
        if r["groups"] > len(r["plots"]) else ""
    rows = [[f"{x['unit']}", _e(x["table"]), _e(x["address"]), _e(x["name"]), _e(x["eng_unit"]), _n(x["changes"]),
             _n(x["samples"]), _n(x["min"]), _n(x["max"]), _n(x["last"]), _e(x["text"])] for x in r["rows"]]
    head = ["unit", "table", "address", "name", "unit of value", "changes", "samples", "min", "max", "last", "text"]
    return _section("registers", "Register trends (registers whose value changed)",
                    f'<div class="grid">{plots}</div>{more}' + _table(head, rows))


def _timeline(d: dict) -> str:
    t = d["timeline"]
    if not t["events"]:
        return _section("timeline", "Writes and faults", "<p>No write and no fault.</p>")
    rows = []
    for e in t["events"]:
        out = ", ".join(f"{k} ×{v}" for k, v in (e.get("outcomes") or {}).items())
        rows.append([f'<span class="k-{e["kind"]}">{e["kind"]}</span>', f"{e['unit']}", _n(round(e["t"], 6)),
                     _n(round(e["t_end"], 6)), _n(e["n"]), _e(e["text"]), _e(out), f"#{e['frame']}",
                     f"{e['capture'] + 1}"])
    more = f"<p class=\"note\">{t['dropped']:,} events between these not listed.</p>" if t["dropped"] else ""
    head = ["kind", "unit", "first s", "last s", "times", "what", "outcome", "frame", "capture"]
    return _section("timeline", "Writes and faults", _plot("plot-timeline", "Timeline: writes (◆) and faults (bars)",
                                                           "hover for the event")
                    + f'<div class="scroll">{_table(head, rows)}</div>' + more)


COMPARE_ROWS = 200  # rows per table of the comparison (the whole text is below them)


def _vals(v: dict) -> str:
    more = f" (+{v['n_values'] - len(v['values'])} more)" if v["n_values"] > len(v["values"]) else ""
    rng = f" range {v['range'][0]}..{v['range'][1]}" if v.get("range") and v["n_values"] > 1 else ""
    return escape(", ".join(str(x) for x in v["values"]) + more + rng)


def _capped(head: list[str], rows: list[list[str]]) -> str:
    more = f'<p class="note">and {len(rows) - COMPARE_ROWS:,} more (in the text below)</p>' \
        if len(rows) > COMPARE_ROWS else ""
    return _table(head, rows[:COMPARE_ROWS]) + more


def _compare(c: dict) -> str:
    d = c["diff"]
    verdict = "same" if c["same"] else "differ"
    out = [f'<p class="verdict {verdict}">{"no semantic difference" if c["same"] else "the captures differ"}</p>',
           f'<p>before: <code>{_e(d["a"])}</code> ({_n(d["frames"]["a"])} frames) · after: <code>{_e(d["b"])}</code>'
           f' ({_n(d["frames"]["b"])} frames)</p>']
    la, lb = d["latency_ms"]["a"], d["latency_ms"]["b"]
    out.append(_table(["latency", "before", "after"], [["median ms", _n(la["median"]), _n(lb["median"])],
                                                       ["p95 ms", _n(la["p95"]), _n(lb["p95"])],
                                                       ["latencies measured", _n(la["n"]), _n(lb["n"])]]))
    u = d["units"]
    if u["added"] or u["removed"]:
        out.append(f"<h3>Units</h3><p>{_e(' '.join(u['a']))} → {_e(' '.join(u['b']))}: added "
                   f"{_e(', '.join(u['added']) or None)}, gone {_e(', '.join(u['removed']) or None)}</p>")
    k = d["codes"]
    rows = ([[f"<code>{_e(x)}</code>", "0", _n(n)] for x, n in k["new"].items()]
            + [[f"<code>{_e(x)}</code>", _n(n), "0"] for x, n in k["vanished"].items()]
            + [[f"<code>{_e(x)}</code>", _n(n[0]), _n(n[1])] for x, n in k["count_changed"].items()])
    if rows:
        out.append("<h3>Errors and annotations</h3>" + _capped(["code", "before", "after"], rows))
    g = d["registers"]
    rows = ([[_e(x), _vals(v["a"]), _vals(v["b"])] for x, v in g["changed"].items()]
            + [[_e(x), "–", _vals(v)] for x, v in g["added"].items()]
            + [[_e(x), _vals(v), "–"] for x, v in g["removed"].items()])
    if rows:
        out.append("<h3>Register values</h3>" + _capped(["register", "before", "after"], rows))
    r = d["requests"]
    rows = ([[_e(x), "–", f"×{v['count']}" + (f" every {v['period_ms']} ms" if v["period_ms"] else "")]
             for x, v in r["added"].items()]
            + [[_e(x), f"×{v['count']}", "–"] for x, v in r["removed"].items()]
            + [[_e(x), f"every {_n(v[0])} ms", f"every {_n(v[1])} ms"] for x, v in r["period_changed"].items()])
    if rows:
        out.append("<h3>Requests</h3>" + _capped(["request", "before", "after"], rows))
    out.append(f"<details><summary>as <code>sniffer diff</code> prints it</summary><pre>{escape(c['text'])}</pre>"
               "</details>")
    return _section("compare", f"Compared with {c['golden']}", "".join(out))
