"""One set of per-unit figures in every view (sniffer/analysis/unitfigures.py; docs/figures.md says what they mean).

One capture goes through every view a user has (the TUI's Units tab under Pilot, the HTML report, the
status file and `sniffer status`, `sniffer diff`, the MQTT health topics on a real broker, the fleet
dataset and its `units` query) and each must show the figures counted here, independently, from the
decoded frames by docs/figures.md's definitions.  Runs `sniffer` as a user would."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from broker import retained

from decoders.registry import code_book
from sniffer.codes import Annotation
from sniffer.frame import Frame, unit_key
from sniffer.capture.session import decode_capture
from sniffer.capture.settings import CaptureSpec
from sniffer.analysis.unitfigures import Latencies, UnitBook

ROOT = Path(__file__).resolve().parent.parent
COUNTS = ("requests", "responses", "crc_errors", "exceptions", "timeouts", "retries", "faults", "alarms", "late",
          "unanswered_at_end", "unmeasured")
LATENCY = ("lat_n", "lat_min", "lat_median", "lat_p95", "lat_p99", "lat_max")


def sniffer(*args, timeout=300) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "sniffer", *map(str, args)], capture_output=True, text=True,
                       timeout=timeout, cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    return r


@pytest.fixture(scope="module", params=["errors-60s", "a510-timeout-5ms"])
def capture(request, tmp_path_factory) -> tuple[Path, list[str]]:
    """(capture, the flags every view decodes it with).  The issue's capture: the errors scenario, a minute,
    seed 11 (CRC-bad requests left unanswered, retries, exceptions, a unit that never answers, ghost units
    from damaged addresses); and an A510 capture decoded with a 5 ms response timeout (drive faults, late
    responses, requests the timeout settled)."""
    if request.param == "a510-timeout-5ms":
        return ROOT / "captures" / "sim" / "a510.mcap", ["--timeout-ms", "5"]
    out = tmp_path_factory.mktemp("cap") / "errors.mcap"
    r = sniffer("simulate", "--scenario", "errors", "--duration", "60", "--seed", "11", "--out", out)
    assert r.returncode == 0, r.stderr
    return out, []


def nearest_rank(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[max(1, math.ceil(round(q * len(s), 9))) - 1]


def expected(frames) -> dict[str, dict]:
    """Every unit's figures by docs/figures.md, counted from the frames without analysis/unitfigures.py."""
    units: dict[str, dict] = {}
    lat: dict[str, list] = {}
    for f in frames:
        if f.unit is None or f.protocol == "noise":
            continue
        name = str(unit_key(f))
        u = units.setdefault(name, dict.fromkeys(COUNTS, 0) | {"ghost": True})
        said = {a.code for a in f.annotations}
        req, rsp = f.role == "request", f.role == "response"
        u["requests"] += req
        u["responses"] += rsp
        u["crc_errors"] += f.crc_ok is False
        u["ghost"] &= f.crc_ok is not True
        u["exceptions"] += rsp and bool(f.exception)
        u["timeouts"] += req and bool(said & {"pair.no_response", "pair.timeout"})
        u["retries"] += req and "pair.retry" in said
        u["faults"] += "model.fault" in said
        u["alarms"] += "model.alarm" in said
        u["late"] += rsp and "pair.late_response" in said
        u["unanswered_at_end"] += req and "pair.end_of_capture" in said
        if rsp and f.pair is not None:
            if f.latency_ms is None:
                u["unmeasured"] += 1
            else:
                lat.setdefault(name, []).append(f.latency_ms)
    for name, u in units.items():
        v = lat.get(name, [])
        u.update(lat_n=len(v), lat_min=min(v, default=None), lat_max=max(v, default=None))
        for key, q in (("lat_median", 0.5), ("lat_p95", 0.95), ("lat_p99", 0.99)):
            u[key] = nearest_rank(v, q) if v else None
    return units


def figures(rows: dict[str, dict], keys=COUNTS + LATENCY) -> dict[str, dict]:
    return {name: {k: row.get(k) for k in keys} for name, row in rows.items()}


def ms3(v) -> str:
    return "-" if v is None else f"{v:.3f}"


# ------------------------------------------------------------------ every view, one capture
def test_every_view_shows_the_same_figures(capture, tmp_path, mqtt_broker):
    capture, flags = capture
    spec = CaptureSpec.of(timeout_ms=float(flags[1])) if flags else None
    session = decode_capture(capture, spec)
    frames = list(session)
    want = expected(frames)
    total = {k: sum(u[k] for u in want.values()) for k in COUNTS}
    if flags:
        assert total["faults"] and total["late"] and total["timeouts"] and total["exceptions"]
    else:
        assert total["timeouts"] and total["retries"] and total["exceptions"] and total["crc_errors"]
        assert any(u["ghost"] for u in want.values())
        assert [f for f in frames if f.role == "request" and f.crc_ok is False and f.pair is None and f.unit], \
            "the capture must hold a damaged request left unanswered (a timeout)"
    want_figures = figures(want)
    good = {name for name, u in want.items() if not u["ghost"]}

    # the model itself
    book = UnitBook()
    for f in frames:
        book.frame(f)
    assert figures(book.to_dict()) == want_figures

    # the report: its units table, and its errors over time add up to the same
    html = tmp_path / "r.html"
    assert sniffer("report", capture, "--out", html, *flags).returncode == 0
    m = re.search(r'<script type="application/json" id="report-data">(.*?)</script>', html.read_text(), re.S)
    data = json.loads(m.group(1).replace("<\\/", "</"))
    report = {u["unit"]: u for u in data["units"]}
    assert figures(report) == want_figures
    assert {name for name, u in report.items() if u["ghost"]} == set(want) - good
    b = data["buckets"]
    for col, fig in (("timeouts", "timeouts"), ("retries", "retries"), ("exceptions", "exceptions"),
                     ("crc", "crc_errors")):
        assert sum(b[col]) == sum(u[fig] for u in want.values()), col

    # a replay keeping a status file and publishing to MQTT: the status file, `sniffer status`, the health topics
    status = tmp_path / "status.json"
    r = sniffer("replay", capture, "--quiet", "--status", status, "--mqtt", mqtt_broker.url(), *flags)
    assert r.returncode == 0, r.stderr
    st = json.loads(status.read_text())
    assert figures(st["units"]) == want_figures
    for key, fig in (("crc", "crc_errors"), ("exceptions", "exceptions"), ("timeouts", "timeouts"),
                     ("retries", "retries"), ("faults", "faults"), ("alarms", "alarms")):
        assert st["errors"][key] == sum(u[fig] for u in want.values()), key
    text = sniffer("status", status).stdout
    for name, u in want.items():
        line = next(x for x in text.splitlines() if x.startswith(f"unit {name} "))
        assert f"req {u['requests']}, rsp {u['responses']}, CRC err {u['crc_errors']}, exc {u['exceptions']}, " \
               f"timeouts {u['timeouts']}, retries {u['retries']}" in line, line
        if u["lat_n"]:
            assert f"median {ms3(u['lat_median'])} p95 {ms3(u['lat_p95'])} max {ms3(u['lat_max'])} ms" in line
    health = {t.split("/")[-2]: json.loads(p) for t, p in retained(mqtt_broker, "plant/line3/+/+/health").items()}
    assert set(health) == good  # a ghost unit gets no health topic (nor a Home Assistant device)
    for name, h in health.items():
        lat = h["latency_ms"]
        got = {k: h[k] for k in COUNTS} | {"lat_n": lat["n"], "lat_min": lat["min"], "lat_median": lat["median"],
                                           "lat_p95": lat["p95"], "lat_p99": lat["p99"], "lat_max": lat["max"]}
        assert got == want_figures[name], name

    # sniffer diff: every unit's figures (the units it lists are those seen in CRC-good frames)
    r = sniffer("diff", capture, capture, "--format", "json", *flags)
    assert r.returncode == 0, r.stdout
    d = json.loads(r.stdout)
    assert figures(d["figures"]["a"]) == {n: v for n, v in want_figures.items() if n in good}
    assert d["figures"]["changed"] == {}

    # the fleet dataset and its `units` query
    ds = tmp_path / "fleet"
    assert sniffer("export", capture, "--to", "dataset", ds, *flags).returncode == 0
    r = sniffer("query", ds, "--preset", "units", "--format", "json")
    assert r.returncode == 0, r.stderr
    rows = json.loads(r.stdout)
    assert {row["link"] for row in rows} == {"default"}
    assert figures({str(row["unit"]): row for row in rows}) == want_figures
    assert {str(row["unit"]) for row in rows if row["ghost"]} == set(want) - good

    # the TUI: the Units tab under Pilot, each cell the figure to the microsecond
    from test_tui import loaded, run

    from sniffer.tui.app import SnifferApp
    from sniffer.tui.sink import TuiSink
    from sniffer.tui.units import COLUMNS

    sink = TuiSink()  # as a finished `replay --tui` leaves it: every frame pending
    sink.start(session.info)
    sink.frames(frames)
    sink.close()

    async def go():
        app = SnifferApp(sink, None, source_label=capture.name, registry=session.registry, clock=lambda: 0.0)
        async with app.run_test(size=(200, 50)) as pilot:
            await loaded(app, pilot)
            await pilot.press("2")
            await pilot.pause()
            table = app.query_one("#unitstable")
            assert table.row_count == len(want)
            col = {c: i for i, c in enumerate(COLUMNS)}
            for name, u in want.items():
                cells = [str(c) for c in table.get_row(name)]
                shown = {k: cells[col[c]] for k, c in (("requests", "req"), ("responses", "rsp"),
                                                       ("crc_errors", "CRC err"), ("exceptions", "exc"),
                                                       ("timeouts", "timeouts"), ("retries", "retries"),
                                                       ("faults", "faults"), ("alarms", "alarms"))}
                assert shown == {k: str(u[k]) for k in shown}, name
                assert [cells[col[c]] for c in ("lat min", "lat median", "lat p95", "lat max")] == \
                    [ms3(u[k]) for k in ("lat_min", "lat_median", "lat_p95", "lat_max")], name
            assert figures(app.store.units.to_dict()) == want_figures
    run(go())


# ------------------------------------------------------------------ the definitions, each a class of frames
def _frame(index, t_ms, role, *codes, unit=1, crc_ok=True, pair=None, latency_ms=None) -> Frame:
    t = int(t_ms * 1e6)
    f = Frame(index, t, t + 4_000_000, b"\x01\x03\x00\x00\x00\x01\x84\x0a", "modbus-rtu", unit, 3, crc_ok=crc_ok)
    f.role, f.pair, f.latency_ms = role, pair, latency_ms
    f.annotations.extend(Annotation(c, "warning", "", 0, 8) for c in codes)
    return f


def test_a_request_that_waited_past_its_timeout_is_one_timeout():
    """The pairer marks such a request pair.no_response and pair.timeout: one request unanswered, one timeout
    (the report and the status file counted each annotation)."""
    book = UnitBook()
    book.frame(_frame(0, 0, "request", "pair.no_response", "pair.timeout"))
    book.frame(_frame(1, 10, "request", "pair.no_response"))  # the next request came first: a timeout too
    assert book[1].timeouts == 2 and book[1].requests == 2


def test_end_of_capture_and_late_responses_are_not_timeouts():
    book = UnitBook()
    book.frame(_frame(0, 0, "request", pair=1))
    book.frame(_frame(1, 1500, "response", "pair.late_response", pair=0, latency_ms=1496.0))
    book.frame(_frame(2, 1600, "request", "pair.end_of_capture"))
    u = book[1]
    assert (u.timeouts, u.late, u.unanswered_at_end, u.responses) == (0, 1, 1, 1)
    assert u.latency.n == 1 and u.latency.max == 1496.0  # a late answer's latency counts


def test_a_damaged_request_left_unanswered_is_a_request_a_crc_error_and_a_timeout():
    """The unit ignores a request the line damaged; the master sees a timeout.  Every view counts it so (the
    report and diff left CRC-bad frames out of the requests and timeouts: unit 2's 10 timeouts read 0)."""
    book = UnitBook()
    book.frame(_frame(0, 0, "request", "pair.no_response", crc_ok=False))
    u = book[1]
    assert (u.requests, u.crc_errors, u.timeouts, u.ghost) == (1, 1, 1, True)
    book.frame(_frame(1, 100, "request", pair=2))
    assert not u.ghost


def test_quantiles_by_the_nearest_rank_exact_then_within_a_tenth_of_a_percent():
    import random

    rng = random.Random(7)
    small = Latencies()
    xs = [round(rng.lognormvariate(1.5, 0.6), 3) for _ in range(2000)]
    for x in xs:
        small.add(x)
    assert small.exact
    for q in (0.01, 0.07, 0.5, 0.95, 0.99, 1.0):
        assert small.quantile(q) == nearest_rank(xs, q), q
    assert small.median == sorted(xs)[999]  # the lower middle of an even count
    big = Latencies()
    ys = [round(rng.lognormvariate(2.5, 1.2), 3) for _ in range(200_000)]
    for y in ys:
        big.add(y)
    assert not big.exact and len(big._counts) <= 12_000  # flat: buckets, not samples
    assert (big.min, big.max) == (min(ys), max(ys))
    for q in (0.05, 0.5, 0.95, 0.99, 0.999):
        want = nearest_rank(ys, q)
        assert abs(big.quantile(q) - want) <= want / 1024 + 0.0005, q


def test_no_module_keeps_its_own_list_of_codes():
    """What a code counts as is declared with it (`Code.category`, gathered by decoders.registry.code_book); no
    module names a categorised code in a string (a set, a dict, a comparison, an SQL list) to decide what it
    counts as.  Prose may name one (a message, a page's text), and a declaration `Code("...", ...)` does."""
    import ast

    categorised = set(code_book().categories)
    found = []
    for path in sorted([*(ROOT / "sniffer").rglob("*.py"), *(ROOT / "decoders").rglob("*.py")]):
        text = path.read_text(encoding="utf-8")
        if not any(c in text for c in categorised):
            continue
        tree = ast.parse(text)
        docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                      if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef))
                      and n.body and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        declared = {id(n.args[0]) for n in ast.walk(tree)
                    if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "Code" and n.args}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
                    and id(node) not in declared):
                hits = [c for c in categorised if node.value == c or f"'{c}'" in node.value]
                if hits:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {sorted(hits)}")
    assert found == []
