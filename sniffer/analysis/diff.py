"""`sniffer diff`: what two captures *say*, compared: units, request sets and poll periods,
register values, new/vanished annotation codes, the units' figures, latency shift.

Each capture is summarised incrementally as it decodes (`Summary.add(frame)`),
so memory does not grow with its length: per request key and per register a
few numbers, the first distinct values, and quantiles that are exact up to
`Quantiles.EXACT` samples and within 0.1 % beyond (a log-bucket histogram).

In a capture of several links a unit is a unit of its link: units, requests,
registers and latencies are keyed by (link, unit) and named `LINK:UNIT`
(`LINK:u1 ...` for requests and registers); a one-line capture names them as before.
"""

from __future__ import annotations

import math
import statistics
from array import array
from collections import Counter
from dataclasses import dataclass

from sniffer.frame import Frame
from sniffer.protocols import MODBUS_TABLES
from sniffer.analysis.unitfigures import UnitBook, UnitFigures

FIRST_VALUES = 8  # distinct values listed per register
MAX_DISTINCT = 1024  # distinct values counted per register (beyond: "1024+")


class Quantiles:
    """Median / percentiles of a stream: exact for the first EXACT samples, then a 0.1 % histogram."""

    EXACT = 10_000  # samples kept exactly (80 kB a request key); beyond, a 0.1 % log histogram
    _LOG = math.log1p(0.001)

    def __init__(self) -> None:
        self.n = 0
        self._xs: array | None = array("d")
        self._hist: Counter | None = None
        self._low = 0  # samples <= 0 (kept apart from the log buckets)

    def add(self, x: float) -> None:
        self.n += 1
        if self._xs is not None:
            self._xs.append(x)
            if len(self._xs) > self.EXACT:
                self._hist = Counter()
                xs, self._xs = self._xs, None
                for v in xs:
                    self._bucket(v)
            return
        self._bucket(x)

    def _bucket(self, x: float) -> None:
        if x <= 0:
            self._low += 1
        else:
            self._hist[math.floor(math.log(x) / self._LOG)] += 1

    def _at(self, k: int) -> float:
        """The k-th smallest sample (0-based) from the histogram."""
        if k < self._low:
            return 0.0
        seen = self._low
        for b in sorted(self._hist):
            seen += self._hist[b]
            if seen > k:
                return math.exp((b + 0.5) * self._LOG)
        return math.exp((max(self._hist) + 0.5) * self._LOG)

    def pct(self, q: float) -> float | None:
        """The sample at rank round(q * (n - 1)), rounded to 3 decimals."""
        if not self.n:
            return None
        k = min(self.n - 1, max(0, int(round(q * (self.n - 1)))))
        if self._xs is not None:
            return round(sorted(self._xs)[k], 3)
        return round(self._at(k), 3)

    def median(self) -> float | None:
        """statistics.median (the mean of the middle two for an even count)."""
        if not self.n:
            return None
        if self._xs is not None:
            return statistics.median(self._xs)
        lo, hi = (self.n - 1) // 2, self.n // 2
        return (self._at(lo) + self._at(hi)) / 2


def request_key(f: Frame) -> tuple:
    """(function, first address, count) of a request; address/count None when not a register access."""
    adu, fc = f.adu, f.function
    if fc in (1, 2, 3, 4, 15, 16) and len(adu) >= 6:
        return fc, int.from_bytes(adu[2:4], "big"), int.from_bytes(adu[4:6], "big")
    if fc in (5, 6) and len(adu) >= 4:
        return fc, int.from_bytes(adu[2:4], "big"), 1
    return fc, None, None


def key_text(k: tuple) -> str:
    fc, addr, n = k
    if addr is None:
        return f"fc{fc:02X}" if fc is not None else "fc--"
    return f"fc{fc:02X} {MODBUS_TABLES.get(fc, '?')} {addr}..{addr + n - 1} ({n})"



def _sort_key(k: tuple) -> tuple:
    return tuple(-1 if x is None else x for x in k)


class Summary:
    """What one capture says, built frame by frame in bounded memory (`to_dict()`: JSON-ready)."""

    def __init__(self) -> None:
        self.frames = 0
        self.figures = UnitBook()  # every unit's figures and latencies (unitfigures: as every view counts them)
        self.requests: dict[tuple, list] = {}  # key -> [count, last t_ns, Quantiles of gaps in ms]
        self.values: dict[tuple, dict] = {}
        self.codes: Counter = Counter()

    def add(self, f: Frame) -> None:
        self.frames += 1
        codes = self.codes
        for a in f.annotations:
            if a.severity != "info":
                codes[a.code] += 1
        self.figures.frame(f)
        if f.crc_ok is False:  # damaged on the line: its unit, function and values are not what was sent
            return
        if f.exception:
            codes[f"exception.{int(f.exception.get('code') or 0):02x}"] += 1
        if f.is_noise or f.unit is None:
            return
        if f.role == "request":
            key = (f.link, f.unit, *request_key(f))
            r = self.requests.get(key)
            if r is None:
                self.requests[key] = [1, f.t_ns, Quantiles()]
            else:
                r[0] += 1
                r[2].add((f.t_ns - r[1]) / 1e6)
                r[1] = f.t_ns
        for pt in f.points:
            self._value((f.link, f.unit, pt.get("address"), pt.get("name") or ""), pt.get("value"))

    def _value(self, key: tuple, v) -> None:
        r = self.values.get(key)
        if r is None:
            r = self.values[key] = {"first": [], "distinct": set(), "more": False, "last": v, "lo": None, "hi": None}
        if v not in r["first"] and len(r["first"]) < FIRST_VALUES:
            r["first"].append(v)
        d = r["distinct"]
        if not r["more"]:
            try:
                d.add(v)
            except TypeError:  # unhashable (a list): count its text
                d.add(repr(v))
            if len(d) > MAX_DISTINCT:
                r["more"] = True
        r["last"] = v
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            r["lo"] = v if r["lo"] is None or v < r["lo"] else r["lo"]
            r["hi"] = v if r["hi"] is None or v > r["hi"] else r["hi"]

    def to_dict(self) -> dict:
        requests = {}
        for (link, unit, *k), (count, _last, gaps) in sorted(self.requests.items(),
                                                             key=lambda kv: _sort_key(kv[0])):
            med = gaps.median()
            requests[f"{_on(link)}u{unit} {key_text(tuple(k))}"] = {
                "unit": unit, "count": count, "period_ms": round(med, 1) if med is not None else None,
            }
        regs = {}
        for (link, unit, addr, name), r in self.values.items():
            key = f"{_on(link)}u{unit} {addr if addr is not None else '-'} {name}".rstrip()
            n = MAX_DISTINCT if r["more"] else len(r["distinct"])
            regs[key] = {"unit": unit, "address": addr, "name": name, "values": list(r["first"]),
                         "n_values": n, "n_values_capped": r["more"], "last": r["last"],
                         "range": [r["lo"], r["hi"]] if r["lo"] is not None else None}
        units = {name: fig for name, fig in self.figures.to_dict().items() if not fig["ghost"]}
        lat = self.figures.latency
        return {
            "frames": self.frames,
            "units": units,
            "requests": requests,
            "registers": regs,
            "codes": dict(sorted(self.codes.items())),
            "latency_ms": {"n": lat.n, "median": lat.median, "p95": lat.quantile(0.95),
                           "per_unit": {name: {"n": u["lat_n"], "median": u["lat_median"], "p95": u["lat_p95"]}
                                        for name, u in units.items() if u["lat_n"]}},
        }


def _on(link: str) -> str:
    """'LINK:' before a unit of one link of several; '' for one line."""
    return f"{link}:" if link else ""


def summarize(frames) -> dict:
    """Summary of an iterable of frames (a decode_capture session, a list)."""
    s = Summary()
    for f in frames:
        s.add(f)
    return s.to_dict()


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
        changed = d.get("figures", {}).get("changed") or {}
        if changed:
            out.append("unit figures:")
            out += [f"  ~ unit {u}: " + ", ".join(f"{k.replace('_', ' ')} {a} -> {b}" for k, (a, b) in ch.items())
                    for u, ch in changed.items()]
        la, lb = d["latency_ms"]["a"], d["latency_ms"]["b"]
        out.append(f"latency: median {la['median']} -> {lb['median']} ms, p95 {la['p95']} -> {lb['p95']} ms "
                   f"(n {la['n']} -> {lb['n']})")
        out.append("no semantic difference" if self.same else "captures differ")
        return "\n".join(out) + "\n"


def _vals(v: dict) -> str:
    s = ", ".join(str(x) for x in v["values"])
    capped = "+" if v.get("n_values_capped") else ""
    more = f" (+{v['n_values'] - len(v['values'])}{capped} more)" if v["n_values"] > len(v["values"]) else ""
    rng = f" range {v['range'][0]}..{v['range'][1]}" if v.get("range") and v["n_values"] > 1 else ""
    return f"[{s}{more}]{rng}"


def _period_changed(pa, pb, rel: float = 0.1) -> bool:
    if pa is None or pb is None:
        return pa != pb
    return abs(pa - pb) > rel * max(pa, pb)


def compare(sa: dict, sb: dict, a: str, b: str) -> DiffReport:
    """The semantic diff of two summaries (`Summary.to_dict()`), named a and b."""
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
        # every unit's figures (unitfigures), and per unit in both the counts that differ
        "figures": {"a": ua, "b": ub,
                    "changed": {u: ch for u in ua if u in ub
                                and (ch := {k: [ua[u][k], ub[u][k]] for k in UnitFigures.COUNTS
                                            if ua[u].get(k) != ub[u].get(k)})}},
    }
    return DiffReport(a, b, data)
