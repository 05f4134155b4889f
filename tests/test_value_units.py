"""Values keep their unit: decoder state that scales or names a value is the same in every view and at every time.

A simulated TDS-V8 line whose PLC reads Cn-02 (the maximum frequency every frequency is a fraction of)
only 10 s in: before that its frequencies are provisional, % of Cn-02, under names of their own, so a
filter, a trigger or a plot of "Output frequency" only ever sees Hz.  A bus file can state Cn-02.  A
unit identified from its answers is drawn under its model's names only from then on (the report's
trends, the TUI's register history).  An A510 is decoded at 0.1 Hz per count only once the drive
confirms a value that cannot be 0.01 Hz, and what a registry knows is carried into a fresh one.
"""

from __future__ import annotations

from collections import defaultdict

import pytest
from helpers import bursts, decoded, fr, simulated

from decoders.registry import default_registry
from decoders.tables import load_map
from decoders.tds_v8.schema import MAP_PATH as TDS_MAP
from sniffer.cli import main
from sniffer.events import CaptureInfo
from sniffer.filterlang import Context, Query
from sniffer.filterlang.facts import register_ids
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.capture.session import CaptureSpec

LATE_CN02 = ("--scenario", "tds-v8", "--param", "startup_polls=()", "--duration", "30", "--seed", "3")
SCALED = {r.name for r in load_map(TDS_MAP).registers.values() if r.scale_by}  # "Output frequency", ...


@pytest.fixture(scope="module")
def late(tmp_path_factory):
    """(info, frames) of the simulated TDS-V8 line that reads Cn-02 late, and when each unit first read it."""
    info, frames = decoded(simulated(tmp_path_factory, "tds.mcap", *LATE_CN02))
    first: dict[int, int] = {}
    for f in frames:
        if f.role == "response" and any(p.get("id") == "Cn-02" for p in f.points):
            first.setdefault(f.unit, f.t_ns)
    assert set(first) == {1, 2}
    return info, frames, first


def units_by_name(frames) -> dict[tuple[int, str], set]:
    out = defaultdict(set)
    for f in frames:
        for p in f.points:
            out[(f.unit, p["name"])].add(p.get("unit"))
    return out


def test_a_value_scaled_by_a_register_not_known_yet_is_provisional_and_named_apart(late):
    _info, frames, first = late
    provisional = [(f, p) for f in frames for p in f.points if p.get("provisional")]
    scaled = [(f, p) for f in frames for p in f.points if p["name"] in SCALED]
    assert provisional and scaled
    for f, p in provisional:
        assert p["unit"] == "%" and p["name"] == f"{p['name'].split(' (% of')[0]} (% of Cn-02)"
        assert p["name"] not in SCALED and f.t_ns < first[f.unit]
        assert "model.scale.pending" in [a.code for a in f.annotations]
    assert all(p["unit"] == "Hz" and f.t_ns > first[f.unit] for f, p in scaled)
    # the rule itself: within the capture a name (of a unit) never changes its engineering unit
    assert {k: v for k, v in units_by_name(frames).items() if len(v) > 1} == {}


def test_the_register_watch_and_the_report_draw_percent_and_hz_as_two_series(late):
    from sniffer.report.collect import Collector
    from sniffer.tui.store import FrameStore

    info, frames, first = late
    store = FrameStore(info.t0_ns)
    store.add(frames)
    rv = store.registers[(1, "holding", 0x0025)]
    assert (rv.name, rv.eng_unit) == ("Output frequency", "Hz")
    assert min(rv.history.t) > first[1] and max(rv.history.v) <= 60.0  # no % sample in the Hz trace
    c = Collector()
    for f in frames:
        c.frame(f)
    rows = {(r["unit"], r["name"]): r for r in c.to_data()["registers"]["rows"] if r["address"] == "0025H"}
    assert rows[("1", "Un-02 Output frequency (% of Cn-02)")]["eng_unit"] == "%"  # the report keeps both
    hz = rows[("1", "Un-02 Output frequency")]
    assert hz["eng_unit"] == "Hz" and hz["max"] <= 60.0


def test_filters_and_triggers_never_compare_a_provisional_value_with_the_scaled_one(late):
    info, frames, first = late
    ctx = Context(info.t0_ns, register_ids(default_registry()))

    def hits(expr):
        q = Query(expr)
        return [f for f in frames if q.matches(f, ctx)]

    def over(f, name, unit, limit=45):
        return any(p["name"] == name and p["unit"] == unit and p["value"] > limit for p in f.points)

    for expr in ('"Output frequency" > 45', "Un-02 > 45", "0025H > 45", "holding[0025H] > 45Hz"):
        got = hits(expr)
        assert got and all(over(f, "Output frequency", "Hz") for f in got), expr
    ahead = [f for f in frames if over(f, "Output frequency (% of Cn-02)", "%")]
    assert ahead, "the drives run above 45 % before Cn-02 is read: the case the rule must not take"
    assert hits('"Output frequency (% of Cn-02)" > 45') == ahead
    assert hits("0025H > 45%") == ahead  # by register, with the provisional value's own unit


def test_a_bus_file_states_a_parameter_the_bus_has_not_shown_yet(late, tmp_path, tmp_path_factory):
    _info, frames, _first = late
    bus = tmp_path / "line.toml"
    bus.write_text('[units]\n1 = "tds-v8"\n2 = "tds-v8"\n\n'
                   '[parameters]\n1 = { "Cn-02" = 60 }\n2 = { "cn-02" = "60 Hz" }\n')
    _, given = decoded(simulated(tmp_path_factory, "tds.mcap", *LATE_CN02), CaptureSpec.of(bus_file=str(bus)))
    assert not any(p.get("provisional") for f in given for p in f.points)
    old = {(f.index, p["address"]): p for f in frames for p in f.points if p.get("provisional")}
    for f in given:  # every frequency the bus file let us scale: the % value times Cn-02 (60 Hz)
        for p in f.points:
            was = old.get((f.index, p["address"]))
            if was is not None:
                assert p["unit"] == "Hz" and p["name"] in SCALED and p["value"] == pytest.approx(was["value"] * 0.6,
                                                                                                abs=0.011)
    assert len(old) > 100


@pytest.mark.parametrize("params, says", [
    ('1 = { "Cn-99" = 60 }', "parameters of unit 1: tds-v8 has no parameter 'Cn-99'"),
    ('1 = { "Cn-02" = "60 V" }', "parameters of unit 1: tds-v8 Cn-02 is in Hz, not V"),
    ('1 = { "Cn-02" = 900 }', "parameters of unit 1: tds-v8 Cn-02 = 900: outside the manual's range 500..4000 (raw)"),
    ('1 = { "Cn-02" = 60.05 }', "parameters of unit 1: tds-v8 Cn-02 = 60.05: not a whole number of 0.1 Hz"),
    ('3 = { "Cn-02" = 60 }', "parameters of unit 3: give its model (--device 3=MODEL, or the bus file's [units]): "
                             "its parameters are named by that model's manual"),
    ('1 = 60', "[parameters] 1 must be a table of the manual's ids and values (e.g. 1 = { \"Cn-02\" = 60 }), not 60"),
    ('1 = { "Cn-02" = true }', "[parameters] 1.'Cn-02' must be a number in the register's unit (or a string such as "
                               "\"60 Hz\"), not True"),
])
def test_a_bad_parameter_is_one_line(tmp_path, capsys, params, says):
    bus = tmp_path / "line.toml"
    bus.write_text(f'[units]\n1 = "tds-v8"\n\n[parameters]\n{params}\n')
    capsys.readouterr()
    assert main(["decode", "--bus", str(bus), "010300250001940F"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"sniffer: error: {bus}: {says}"]


# ------------------------------------------------------------------ a unit identified late
def test_a_unit_is_drawn_as_its_model_only_from_its_identification_on(tmp_path, tmp_path_factory):
    """An A510 byte capture (no metadata: nothing says the units' model): the first answers are decoded as
    generic registers (raw numbers), the rest as the A510's, scaled.  The report's trends and the TUI's
    register history draw each under what it was decoded as: no Hz trend holds a raw generic number."""
    from sniffer.report.collect import Collector
    from sniffer.capture.session import decode_capture
    from sniffer.analysis.register_book import RegisterBook

    csv = simulated(tmp_path_factory, "a510.csv", "--scenario", "a510", "--duration", "8", "--seed", "2")
    session = decode_capture(csv, CaptureSpec.of(baud=19200, parity="N", stopbits=1))
    c, book = Collector(), RegisterBook()
    c.begin(str(csv), session)
    models = set()
    for f in session:
        models.add(f.model)
        c.frame(f)
        book.frame(f)
    c.end(session)
    assert {"generic", "a510"} <= models
    regs = c.to_data()["registers"]
    hz = [s for p in regs["plots"] if p["eng_unit"] == "Hz" for s in p["series"]]
    assert hz and all(v is None or v <= 60.0 for s in hz for v in s["v"])  # the line runs at most at 60 Hz
    early = {(rv.address, rv.name, rv.eng_unit, rv.model) for rv in c.book.retired}
    assert (0x2502, "holding[9474]", None, "generic") in early  # the setpoint's raw number: a series of its own
    for rv in book.values.values():  # the TUI's history: one model, name and unit
        if rv.eng_unit == "Hz":
            assert rv.model == "a510" and all(v <= 60.0 for v in rv.history.v)


# ------------------------------------------------------------------ A510 resolution, carried state
A510_LINE = LineSettings(19200, "N", 1)


def _a510(frames_hex, registry=None):
    info = CaptureInfo(baud=A510_LINE.baud, parity=A510_LINE.parity, stopbits=A510_LINE.stopbits)
    registry = registry or default_registry({1: "a510"})
    p = Pipeline(info, A510_LINE, registry)
    out = []
    for ev in bursts(frames_hex, A510_LINE, gap_chars=20):
        out += p.feed(ev)
    return out + p.flush(), registry


def _freq(frames):
    return [(f.model, p["value"]) for f in frames if f.role == "response" for p in f.points
            if p["name"] == "Output frequency"]


READ_2524 = fr("010325240001")


def test_an_a510_turns_to_0_1_hz_only_on_a_value_the_drive_confirms():
    frames, registry = _a510([
        fr("0106250288B8"), fr("018603"),  # a PLC asks for 35000 counts: refused, nothing confirmed
        READ_2524, fr("0103021388"),  # 5000: 50.00 Hz
        READ_2524, fr("01030288B8"),  # 35000 cannot be 0.01 Hz: the drive runs at 0.1 Hz per count
        READ_2524, fr("0103021388"),  # 5000: 500.0 Hz now
    ])
    assert _freq(frames) == [("a510", 50.0), ("a510-hf", 3500.0), ("a510-hf", 500.0)]
    assert [f.index for f in frames if any(a.code == "a510.freq.high" for a in f.annotations)] == [5]
    assert registry.carried() == {"1": {"extra": {"a510_hf": True}}}
    again, _ = _a510([READ_2524, fr("0103021388")], _carried(registry, {1: "a510"}))
    assert _freq(again) == [("a510-hf", 500.0)]  # the next part starts where this one ended


def _carried(registry, devices=None):
    fresh = default_registry(devices)
    fresh.carry_in(registry.carried())
    return fresh


def test_a_fresh_registry_starts_with_the_models_and_scales_the_last_one_knew(late):
    from sniffer.simulator import get_scenario, simulate, wire_chunks

    sc = get_scenario("tds-v8")
    first = default_registry()  # no device map: the units are identified from their answers
    p = Pipeline(CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits), sc.line, first)
    for ev in wire_chunks(list(simulate(sc, sc.line, 6.0, 1))):
        p.feed(ev)
    p.flush()
    state = first.carried()
    assert {u: (d["model"], d["holding"]) for u, d in state.items()} == {"1": ("tds-v8", {"769": 600}),
                                                                        "2": ("tds-v8", {"769": 600})}
    info = CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits)
    frames = []
    p = Pipeline(info, sc.line, _carried(first))
    for ev in bursts([fr("010300250001"), fr("0103023A98")], sc.line, gap_chars=20):
        frames += p.feed(ev)
    frames += p.flush()
    rsp = frames[-1]  # 15000 of 30000: half of Cn-02 (60.0 Hz), named and scaled from the first answer
    assert (rsp.model, rsp.points[0]["name"], rsp.points[0]["value"], rsp.points[0]["unit"]) == \
        ("tds-v8", "Output frequency", 30.0, "Hz")
