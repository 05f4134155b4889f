"""Regression checks: a capture against its golden decode, and a semantic diff of two captures.

`check(capture, golden)` decodes the capture through the normal pipeline and
compares it with a stored text, one line per frame:

    <t seconds> <latency ms or -> | <content: role, unit, model, fc, crc, pair offset, summary, codes>

Content is compared exactly; the two timing columns within tolerances
(`Tolerances(time_ms=..., latency_ms=...)`), so a golden survives a rounding
change in a clock model but not a changed verdict.  Exit codes: 0 same,
1 different (a unified diff), 2 error (unreadable capture, missing golden).

`diff(a, b)` compares what two captures *say*: units, request sets and poll
periods, register values, new/vanished annotation codes, latency shift.
"""

from __future__ import annotations

import difflib
import os
import statistics
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from .events import CaptureInfo
from .frame import Frame
from .protocols import MODBUS_TABLES

EXIT_SAME, EXIT_DIFFERENT, EXIT_ERROR = 0, 1, 2
GOLDEN_HEADER = "# sniffer golden v1: t_s latency_ms | role unit model fc crc pair(offset) summary [codes]"


@dataclass(frozen=True)
class Tolerances:
    """Timing tolerances; content is always exact."""

    time_ms: float = 1.0  # frame start time
    latency_ms: float = 1.0  # request -> response latency


@dataclass
class DecodeOptions:
    """What `sniffer replay` flags say; None = what the capture (or the default) says."""

    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    devices: dict[int, str] = field(default_factory=dict)
    model_files: list[str] = field(default_factory=list)
    protocol: str | None = None
    timeout_ms: float | None = None
    unit_timeouts: dict[int, float] = field(default_factory=dict)
    input_format: str = "auto"


class _Collect:
    def __init__(self) -> None:
        self.frames: list[Frame] = []

    def start(self, info: CaptureInfo) -> None:
        pass

    def raw(self, event) -> None:
        pass

    def frame(self, f: Frame) -> None:
        self.frames.append(f)

    def close(self) -> None:
        pass


def decode_capture(path: str | os.PathLike[str], opts: DecodeOptions | None = None, sinks=(),
                   on_event=None) -> tuple[CaptureInfo, list[Frame]]:
    """Replay a capture file through the pipeline: (info, decoded frames).

    Raises sniffer.sources.CaptureError for unreadable input or a missing baud
    rate, ValueError for a bad device map.  `sinks` get the frames too;
    `on_event(i, ev)` is called per source event (a progress bar hook).
    """
    from decoders.registry import default_registry

    from .line import LineSettings
    from .pairer import DEFAULT_TIMEOUT_MS
    from .pipeline import Pipeline
    from .sources.replay import open_replay

    opts = opts or DecodeOptions()
    from .sources import CaptureError, pcapsrc

    if opts.input_format == "pcap" or (opts.input_format == "auto" and pcapsrc.sniff(path)):
        info, events = pcapsrc.open_pcap(path)  # until replay.open_replay knows pcap
    else:
        info, events = open_replay(os.fspath(path), opts.input_format)
    baud = opts.baud or info.baud
    if baud is None:
        raise CaptureError(f"{path}: the capture does not say its baud rate: give --baud (baud=)")
    line = LineSettings(int(baud), (opts.parity or info.parity or "N").upper(),
                        int(opts.stopbits or info.stopbits or 1), int(info.databits or 8))
    devices = dict(info.devices or {})
    devices.update(opts.devices or {})
    protocol = opts.protocol or info.protocol or "modbus-rtu"
    # the settings used travel with the frames (an MCAP re-export replays without flags)
    info.devices = devices
    info.baud, info.parity, info.stopbits, info.protocol = line.baud, line.parity, line.stopbits, protocol
    registry = default_registry(devices, opts.model_files or None,
                                default="pd-series" if protocol.startswith("pd-") else "generic")
    col = _Collect()
    p = Pipeline(info, line, registry, [col, *sinks], protocol=protocol,
                 timeout_ms=opts.timeout_ms if opts.timeout_ms is not None else DEFAULT_TIMEOUT_MS,
                 unit_timeouts=dict(opts.unit_timeouts) or None)
    try:
        for i, ev in enumerate(events):
            p.feed(ev)
            if on_event is not None:
                on_event(i, ev)
    finally:
        p.finish()
    return info, col.frames


# ---------------------------------------------------------------- golden text
def golden_line(f: Frame, t0_ns: int) -> str:
    t = (f.t_ns - t0_ns) / 1e9
    lat = "-" if f.latency_ms is None else f"{f.latency_ms:.3f}"
    codes = ",".join(a.code for a in f.annotations)
    tail = f" [{codes}]" if codes else ""
    if f.protocol == "noise":
        content = f"NOISE {len(f.raw)}B {f.raw.hex()} ({f.noise_reason}){tail}"
    else:
        unit = "?" if f.unit is None else str(f.unit)
        fc = "--" if f.function is None else f"{f.function:02X}"
        crc = {True: "ok", False: "BAD", None: "-"}[f.crc_ok]
        # the partner as an offset, not an index: one inserted frame is one diff line
        pair = "-" if f.pair is None else f"{f.pair - f.index:+d}"
        content = (f"{f.role} u{unit} {f.model or '-'} fc{fc} crc={crc} pair={pair} "
                   f"{f.summary}{tail}")
    return f"{t:.6f} {lat} | {content}"


def golden_text(info: CaptureInfo, frames: list[Frame]) -> str:
    return "\n".join([GOLDEN_HEADER, *(golden_line(f, info.t0_ns) for f in frames)]) + "\n"


def _split(line: str) -> tuple[float | None, float | None, str]:
    head, sep, content = line.partition(" | ")
    if not sep:
        return None, None, line
    try:
        t_s, lat_s = head.split(" ")
        return float(t_s), (None if lat_s == "-" else float(lat_s)), content
    except ValueError:
        return None, None, line


def _within(old: str, new: str, tol: Tolerances) -> bool:
    """The same frame: content equal, timing within tolerance."""
    if old == new:
        return True
    t_a, l_a, c_a = _split(old)
    t_b, l_b, c_b = _split(new)
    if c_a != c_b or t_a is None or t_b is None:
        return False
    if abs(t_a - t_b) * 1e3 > tol.time_ms + 1e-9:
        return False
    if (l_a is None) != (l_b is None):
        return False
    return l_a is None or abs(l_a - l_b) <= tol.latency_ms + 1e-9


def compare_text(old: str, new: str, tol: Tolerances = Tolerances(), names=("golden", "capture")) -> str:
    """'' when equal within tolerance, else a unified diff (timing-only noise hidden)."""
    a = old.splitlines()
    b = new.splitlines()
    # a line that matches within tolerance is shown as the golden's, so the diff
    # lists only real changes
    sm = difflib.SequenceMatcher(None, [_split(x)[2] for x in a], [_split(x)[2] for x in b], autojunk=False)
    shown = list(b)
    for tag, i1, i2, j1, j2 in sm.get_opcodes():
        if tag == "equal":
            for k in range(i2 - i1):
                if _within(a[i1 + k], b[j1 + k], tol):
                    shown[j1 + k] = a[i1 + k]
    if shown == a:
        return ""
    return "\n".join(difflib.unified_diff(a, shown, names[0], names[1], lineterm="")) + "\n"


def check(capture, golden, *, tolerances: Tolerances | None = None, update: bool = False,
          options: DecodeOptions | None = None) -> tuple[int, str]:
    """(exit code, text): 0 same, 1 different (unified diff), 2 error (one line)."""
    from decoders.registry import DeviceMapError
    from .sources import CaptureError

    tol = tolerances or Tolerances()
    golden = Path(golden)
    try:
        info, frames = decode_capture(capture, options)
    except (CaptureError, ValueError, DeviceMapError, OSError) as e:
        return EXIT_ERROR, f"sniffer check: error: {e}\n"
    text = golden_text(info, frames)
    if update:
        try:
            old = golden.read_text() if golden.exists() else ""
            golden.parent.mkdir(parents=True, exist_ok=True)
            golden.write_text(text)
        except OSError as e:
            return EXIT_ERROR, f"sniffer check: error: {golden}: {e.strerror or e}\n"
        d = compare_text(old, text, Tolerances(0, 0), (str(golden), str(capture))) if old else ""
        return EXIT_SAME, f"sniffer check: wrote {golden} ({len(frames)} frames)\n" + d
    if not golden.exists():
        return EXIT_ERROR, (f"sniffer check: error: {golden}: no such golden file "
                            "(create it with --update-golden, then review it)\n")
    try:
        old = golden.read_text()
    except OSError as e:
        return EXIT_ERROR, f"sniffer check: error: {golden}: {e.strerror or e}\n"
    d = compare_text(old, text, tol, (str(golden), str(capture)))
    return (EXIT_DIFFERENT, d) if d else (EXIT_SAME, "")


# ---------------------------------------------------------------- semantic diff


def _request_key(f: Frame) -> tuple:
    """(function, first address, count) of a request; address/count None when not a register access."""
    adu, fc = f.adu, f.function
    if fc in (1, 2, 3, 4, 15, 16) and len(adu) >= 6:
        return fc, int.from_bytes(adu[2:4], "big"), int.from_bytes(adu[4:6], "big")
    if fc in (5, 6) and len(adu) >= 4:
        return fc, int.from_bytes(adu[2:4], "big"), 1
    return fc, None, None


def _key_text(k: tuple) -> str:
    fc, addr, n = k
    if addr is None:
        return f"fc{fc:02X}" if fc is not None else "fc--"
    return f"fc{fc:02X} {MODBUS_TABLES.get(fc, '?')} {addr}..{addr + n - 1} ({n})"


def _pct(xs: list[float], q: float) -> float | None:
    if not xs:
        return None
    xs = sorted(xs)
    return round(xs[min(len(xs) - 1, max(0, int(round(q * (len(xs) - 1)))))], 3)


def summarize(info: CaptureInfo, frames: list[Frame]) -> dict:
    """What a capture says, in comparable terms (JSON-ready)."""
    units: dict[int, dict] = {}
    req_times: dict[tuple, list[int]] = defaultdict(list)
    values: dict[tuple, list] = defaultdict(list)
    codes: Counter = Counter()
    lat_all: list[float] = []
    lat_unit: dict[int, list[float]] = defaultdict(list)
    for f in frames:
        for a in f.annotations:
            if a.severity != "info":
                codes[a.code] += 1
        if f.exception:
            codes[f"exception.{int(f.exception.get('code', 0)):02x}"] += 1
        if f.is_noise or f.unit is None:
            continue
        u = units.setdefault(f.unit, {"model": f.model, "requests": 0, "responses": 0})
        u["model"] = u["model"] if u["model"] not in (None, "generic") else f.model
        if f.role == "request":
            u["requests"] += 1
            req_times[(f.unit, *_request_key(f))].append(f.t_ns)
        elif f.role == "response":
            u["responses"] += 1
            if f.latency_ms is not None:
                lat_all.append(f.latency_ms)
                lat_unit[f.unit].append(f.latency_ms)
        if f.crc_ok is False:
            continue
        for pt in f.points:
            values[(f.unit, pt.get("address"), pt.get("name") or "")].append(pt.get("value"))
    requests: dict[str, dict] = {}
    for (unit, *k), ts in sorted(req_times.items(), key=lambda kv: tuple(-1 if x is None else x for x in kv[0])):
        gaps = [(b - a) / 1e6 for a, b in zip(ts, ts[1:])]
        requests[f"u{unit} {_key_text(tuple(k))}"] = {
            "unit": unit, "count": len(ts),
            "period_ms": round(statistics.median(gaps), 1) if gaps else None,
        }
    regs = {}
    for (unit, addr, name), vals in values.items():
        distinct = []
        for v in vals:
            if v not in distinct:
                distinct.append(v)
        key = f"u{unit} {addr if addr is not None else '-'} {name}".rstrip()
        nums = [v for v in vals if isinstance(v, (int, float)) and not isinstance(v, bool)]
        regs[key] = {"unit": unit, "address": addr, "name": name, "values": distinct[:8],
                     "n_values": len(distinct), "last": vals[-1],
                     "range": [min(nums), max(nums)] if nums else None}
    return {
        "frames": len(frames),
        "units": {str(k): v for k, v in sorted(units.items())},
        "requests": requests,
        "registers": regs,
        "codes": dict(sorted(codes.items())),
        "latency_ms": {"n": len(lat_all), "median": _pct(lat_all, 0.5), "p95": _pct(lat_all, 0.95),
                       "per_unit": {str(u): {"n": len(v), "median": _pct(v, 0.5), "p95": _pct(v, 0.95)}
                                    for u, v in sorted(lat_unit.items())}},
    }


@dataclass
class DiffReport:
    a: str
    b: str
    data: dict

    @property
    def same(self) -> bool:
        d = self.data
        return not (d["units"]["added"] or d["units"]["removed"] or d["requests"]["added"]
                    or d["requests"]["removed"] or d["requests"]["period_changed"]
                    or d["registers"]["changed"] or d["registers"]["added"] or d["registers"]["removed"]
                    or d["codes"]["new"] or d["codes"]["vanished"] or d["codes"]["count_changed"])

    def to_dict(self) -> dict:
        return {"a": self.a, "b": self.b, "same": self.same, **self.data}

    def to_text(self) -> str:
        d = self.data
        out = [f"--- {self.a}", f"+++ {self.b}"]
        ua, ub = d["units"]["a"], d["units"]["b"]
        out.append(f"units: {' '.join(ua) or '-'}  ->  {' '.join(ub) or '-'}")
        for u in d["units"]["added"]:
            out.append(f"  + unit {u} ({d['units']['models'].get(u) or 'generic'})")
        for u in d["units"]["removed"]:
            out.append(f"  - unit {u}")
        r = d["requests"]
        if r["added"] or r["removed"] or r["period_changed"]:
            out.append("requests:")
            out += [f"  + {k} x{v['count']}" + (f" every {v['period_ms']} ms" if v["period_ms"] else "")
                    for k, v in r["added"].items()]
            out += [f"  - {k} x{v['count']}" for k, v in r["removed"].items()]
            out += [f"  ~ {k} period {v[0] or '-'} ms -> {v[1] or '-'} ms" for k, v in r["period_changed"].items()]
        g = d["registers"]
        if g["changed"] or g["added"] or g["removed"]:
            out.append("registers:")
            out += [f"  ~ {k}: {_vals(v['a'])} -> {_vals(v['b'])}" for k, v in g["changed"].items()]
            out += [f"  + {k}: {_vals(v)}" for k, v in g["added"].items()]
            out += [f"  - {k}: {_vals(v)}" for k, v in g["removed"].items()]
        c = d["codes"]
        if c["new"] or c["vanished"] or c["count_changed"]:
            out.append("errors / annotations:")
            out += [f"  + {k} x{n}" for k, n in c["new"].items()]
            out += [f"  - {k} x{n}" for k, n in c["vanished"].items()]
            out += [f"  ~ {k} x{n[0]} -> x{n[1]}" for k, n in c["count_changed"].items()]
        la, lb = d["latency_ms"]["a"], d["latency_ms"]["b"]
        out.append(f"latency: median {la['median']} -> {lb['median']} ms, p95 {la['p95']} -> {lb['p95']} ms "
                   f"(n {la['n']} -> {lb['n']})")
        out.append("no semantic difference" if self.same else "captures differ")
        return "\n".join(out) + "\n"


def _vals(v: dict) -> str:
    s = ", ".join(str(x) for x in v["values"])
    more = f" (+{v['n_values'] - len(v['values'])} more)" if v["n_values"] > len(v["values"]) else ""
    rng = f" range {v['range'][0]}..{v['range'][1]}" if v.get("range") and v["n_values"] > 1 else ""
    return f"[{s}{more}]{rng}"


def _period_changed(pa, pb, rel: float = 0.1) -> bool:
    if pa is None or pb is None:
        return pa != pb
    return abs(pa - pb) > rel * max(pa, pb)


def diff(a, b, options: DecodeOptions | None = None, options_b: DecodeOptions | None = None) -> DiffReport:
    """Semantic diff of two captures (decoded with the same options unless options_b)."""
    sa = summarize(*decode_capture(a, options))
    sb = summarize(*decode_capture(b, options_b or options))
    ua, ub = sa["units"], sb["units"]
    ra, rb = sa["requests"], sb["requests"]
    ga, gb = sa["registers"], sb["registers"]
    ca, cb = sa["codes"], sb["codes"]
    data = {
        "units": {"a": list(ua), "b": list(ub), "added": [u for u in ub if u not in ua],
                  "removed": [u for u in ua if u not in ub],
                  "models": {u: v["model"] for u, v in {**ua, **ub}.items()}},
        "requests": {"added": {k: v for k, v in rb.items() if k not in ra},
                     "removed": {k: v for k, v in ra.items() if k not in rb},
                     "period_changed": {k: [ra[k]["period_ms"], rb[k]["period_ms"]] for k in ra
                                        if k in rb and _period_changed(ra[k]["period_ms"], rb[k]["period_ms"])}},
        "registers": {"changed": {k: {"a": ga[k], "b": gb[k]} for k in ga
                                  if k in gb and ga[k]["values"] != gb[k]["values"]},
                      "added": {k: v for k, v in gb.items() if k not in ga},
                      "removed": {k: v for k, v in ga.items() if k not in gb}},
        "codes": {"new": {k: n for k, n in cb.items() if k not in ca},
                  "vanished": {k: n for k, n in ca.items() if k not in cb},
                  "count_changed": {k: [ca[k], cb[k]] for k in ca if k in cb and ca[k] != cb[k]}},
        "latency_ms": {"a": sa["latency_ms"], "b": sb["latency_ms"]},
        "frames": {"a": sa["frames"], "b": sb["frames"]},
    }
    return DiffReport(os.fspath(a), os.fspath(b), data)


__all__ = [
    "check", "compare_text", "decode_capture", "golden_text", "golden_line", "diff", "summarize",
    "DiffReport", "DecodeOptions", "Tolerances", "EXIT_SAME", "EXIT_DIFFERENT", "EXIT_ERROR",
]
