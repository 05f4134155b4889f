"""`sniffer diagnose` on simulated captures of each cause (`simulate --fault KIND[:UNIT]`): each kind is found,
on the right unit, and a healthy line gives nothing above info; no finding names a unit that is only a damaged
address.  The captures are made in-process (the simulator as a session source, as `simulate` makes them)
and diagnosed through the same engine the command uses; the command itself has its own tests below."""

from __future__ import annotations

import json

import pytest

from sniffer.diagnose import KINDS, Diagnosis, to_json
from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.simulator.faults import apply
from sniffer.simulator.sources import SimulatedSource, scenario_named

from helpers import run_sniffer

_CACHE: dict = {}


def diagnose_sim(scenario: str = "default", faults=(), seconds: float = 30.0, adapter: str = "usb", seed: int = 1,
                 params=(), reference=None):
    """(findings, engine) of a simulated capture of `scenario` with `faults` put on the line."""
    key = (scenario, tuple(faults), seconds, adapter, seed, tuple(params), id(reference))
    if key not in _CACHE:
        from sniffer.simulator.overrides import apply as overrides

        sc = apply(overrides(scenario_named(scenario), list(params)), list(faults))
        source = SimulatedSource(sc, sc.line, seconds, seed, adapter)
        session = Session(CaptureSpec.of(), source, [])
        session.open()
        engine = Diagnosis(reference)
        engine.start_session(session)
        for f in session:
            engine.frame(f)
        _CACHE[key] = (engine.findings(), engine)
    return _CACHE[key]


def worst(findings) -> list:
    return [(f.kind, f.unit) for f in findings if f.severity in ("error", "warning")]


def present_units(engine) -> set:
    return {u for link in engine.links.values() for u, x in link.units.items() if x.present}


def assert_blames_only_present_units(findings, engine) -> None:
    units = present_units(engine)
    for f in findings:
        assert f.unit is None or f.unit in units, f"{f.kind} names unit {f.unit}, seen only in damaged frames"


# ------------------------------------------------------------------ healthy lines
@pytest.mark.parametrize("scenario,adapter,seed", [("default", "usb", 1), ("default", "wire", 2), ("fast", "usb", 3),
                                                   ("stress", "wire", 1)])
def test_a_healthy_line_gives_nothing_above_info(scenario, adapter, seed):
    findings, _ = diagnose_sim(scenario, (), 30.0, adapter, seed)
    assert worst(findings) == []
    assert any(f.kind == "poll_cycle" for f in findings)  # what it does say: the cycle and the room left


# ------------------------------------------------------------------ each kind on its unit
NO_TRIPS = ("unit1.trip_every_s=(0.0, 0.0)", "unit2.trip_every_s=(0.0, 0.0)")  # a model scenario's drives trip too
CASES = [
    # (fault, scenario, adapter, kind, unit)
    ("driver_enable_late:2", "default", "usb", "driver_enable_late", 2),
    ("driver_enable_late:5", "default", "wire", "driver_enable_late", 5),
    ("driver_disable_early:5", "default", "usb", "driver_disable_early", 5),
    ("driver_disable_early:1", "default", "wire", "driver_disable_early", 1),
    ("bus_unbiased", "default", "usb", "bus_unbiased", None),
    ("bus_unbiased", "default", "wire", "bus_unbiased", None),
    ("bus_unbiased", "errors", "usb", "bus_unbiased", None),
    ("noise_correlated_with_load:1", "a510", "usb", "noise_correlated_with_load", 1),
    ("noise_correlated_with_load:2", "tds-v8", "wire", "noise_correlated_with_load", 2),
    ("timeout_too_short:2", "default", "usb", "timeout_too_short", 2),
    ("timeout_too_short:5", "default", "wire", "timeout_too_short", 5),
    ("unit_silent:5", "default", "usb", "unit_silent", 5),
    ("unit_silent:7", "default", "wire", "unit_silent", 7),
    ("params_not_saved:2", "tds-v8", "usb", "params_not_saved", 2),
    ("eeprom_wear:1", "tds-v8", "wire", "eeprom_wear", 1),
    ("drive_fault:2", "a510", "usb", "drive_fault", 2),
    ("drive_fault:1", "spl", "wire", "drive_fault", 1),
    ("wrong_line_settings", "default", "usb", "wrong_line_settings", None),
    ("wrong_line_settings:38400", "default", "wire", "wrong_line_settings", None),
    ("second_master:2", "default", "usb", "second_master", 2),
    ("second_master:1", "default", "wire", "second_master", 1),
    ("second_master:1", "errors", "usb", "second_master", 1),  # on a noisy line with a silent unit and retries
    ("latency_drift:1", "default", "wire", "latency_drift", 1),
]


@pytest.mark.parametrize("fault,scenario,adapter,kind,unit", CASES, ids=[f"{c[0]}-{c[2]}" for c in CASES])
def test_each_cause_is_found_on_its_unit(fault, scenario, adapter, kind, unit):
    params = NO_TRIPS if kind == "drive_fault" else ()
    findings, engine = diagnose_sim(scenario, (fault,), 30.0, adapter, params=params)
    hits = [f for f in findings if f.kind == kind]
    assert [f.unit for f in hits] == [unit], [f.headline() for f in findings]
    f = hits[0]
    assert f.severity in ("error", "warning") and f.text and f.action and f.evidence
    assert f.frames and f.t_start is not None and f.t_end >= f.t_start
    assert_blames_only_present_units(findings, engine)
    # a capture of the same scenario without the cause does not find it there (a model scenario has trouble of
    # its own: the TDS-V8 PLC saves unit 2's parameters every 4 s, an eeprom_wear of unit 2)
    clean, _ = diagnose_sim(scenario, (), 30.0, adapter, params=params)
    assert (kind, unit) not in {(x.kind, x.unit) for x in clean if x.severity != "info"}


def test_a_late_drivers_phantom_units_are_its_own():
    """The answers' damaged first byte shows other unit numbers: the finding names them as unit 2's."""
    findings, engine = diagnose_sim("default", ("driver_enable_late:2",), 30.0, "usb")
    (f,) = [x for x in findings if x.kind == "driver_enable_late"]
    phantoms = f.evidence.get("shown_as_units") or []
    assert phantoms and all(p not in present_units(engine) for p in phantoms)
    assert not any(x.kind == "unit_silent" and x.unit == 2 for x in findings)  # its answers are damaged, not absent


def test_statistics_are_given_where_a_finding_rests_on_one():
    findings, _ = diagnose_sim("a510", ("noise_correlated_with_load:1",), 30.0, "usb")
    (f,) = [x for x in findings if x.kind == "noise_correlated_with_load"]
    assert f.statistic["p"] < 1e-4 and f.evidence["rate_above"] > 2 * f.evidence["rate_below"]
    findings, _ = diagnose_sim("default", ("second_master:2",), 30.0, "usb")
    (f,) = [x for x in findings if x.kind == "second_master"]
    assert f.statistic["share"] < 0.45 and f.statistic["n"] >= 30  # its phases keep no place in the cycle


def test_timeout_too_short_recommends_a_timeout_above_the_slowest_answer():
    findings, _ = diagnose_sim("default", ("timeout_too_short:2",), 30.0, "usb")
    (f,) = [x for x in findings if x.kind == "timeout_too_short"]
    ev = f.evidence
    assert ev["master_gives_up_after_ms"] < ev["latency_max_ms"] <= ev["recommended_timeout_ms"]


def test_wrong_line_settings_say_what_to_try():
    findings, _ = diagnose_sim("default", ("wrong_line_settings:38400",), 30.0, "wire")
    (f,) = [x for x in findings if x.kind == "wrong_line_settings"]
    assert f.evidence["baud_from_bursts"] == 19200 and "--baud 19200" in f.action
    assert len(findings) == 1  # nothing else is judged on a line read at the wrong settings
    findings, _ = diagnose_sim("default", (), 10.0, "wire", params=())
    # parity: the baud is right, the UART flags say which parity the line has
    from sniffer.line import LineSettings

    sc = scenario_named("default")
    source = SimulatedSource(sc, sc.line, 10.0, 1, "wire", receiver=LineSettings(19200, "N", 1))
    session = Session(CaptureSpec.of(), source, [])
    session.open()
    engine = Diagnosis()
    engine.start_session(session)
    for fr in session:
        engine.frame(fr)
    (f,) = engine.findings()
    assert f.kind == "wrong_line_settings" and "--parity E" in f.action


@pytest.mark.parametrize("seconds,seed", [(30.0, 1), (60.0, 11), (60.0, 4)])
def test_the_errors_scenario(seconds, seed):
    """What the README shows: the silent unit 9 (a stray burst or a damaged frame after one of its requests
    does not make it a unit that answers), the refused requests, unit 3 answering broadcasts, the damage; no second
    master (its cycle stretched by timeouts and retries, a request type still keeps its place in it)."""
    findings, engine = diagnose_sim("errors", (), seconds, "usb", seed)
    got = worst(findings)
    assert ("unit_silent", 9) in got and ("answers_broadcast", 3) in got
    assert {u for k, u in got if k == "unit_refuses"} == {1, 2, 3}
    # and the scenario's damage (corrupted answers of units 1 and 3, noise bursts) that no cause explains
    assert {k for k, _ in got} == {"unit_silent", "unit_refuses", "answers_broadcast", "line_damage"}
    assert_blames_only_present_units(findings, engine)
    assert findings == sorted(findings, key=lambda f: f.sort_key())  # most severe first
    assert [f.severity for f in findings][0] == "error"


def test_params_against_a_reference(tmp_path):
    from sniffer.diagnose.reference import load_csv

    ref = tmp_path / "drive2.csv"
    ref.write_text("unit,register,value\n2,An-01,20.0\n2,Cn-02,60.0\n1,Cn-02,60.0\n")
    reference = load_csv(str(ref))
    findings, _ = diagnose_sim("tds-v8", (), 20.0, "usb", reference=reference)
    (f,) = [x for x in findings if x.kind == "params_changed"]
    assert f.unit == 2 and [c["parameter"] for c in f.evidence["changes"]] == ["An-01"]
    assert f.evidence["changes"][0]["now"] == 25.0  # the scenario writes and reads back 25.00 Hz
    assert reference.notes() == []  # every row named a register of its unit's map, every unit answered


def test_params_rows_compared_with_nothing_are_said(tmp_path):
    """A register id its unit's map lacks (a typo) and a unit the capture never hears: a note each, not dropped."""
    from sniffer.diagnose.reference import load_csv

    ref = tmp_path / "drive2.csv"
    ref.write_text("unit,register,value\n2,An-01,20.0\n2,An-O1,20.0\n2,Zz-99,1\n9,Cn-02,60.0\n")
    reference = load_csv(str(ref))
    findings, _ = diagnose_sim("tds-v8", (), 20.0, "usb", reference=reference)
    assert [f.unit for f in findings if f.kind == "params_changed"] == [2]
    notes = reference.notes()
    assert len(notes) == 2, notes
    assert "2 rows of unit 2 name no register of its map" in notes[0] and "'An-O1', 'Zz-99'" in notes[0]
    assert notes[1] == "--params drive2.csv: unit 9 never answered in the capture; not compared"


def test_json_has_every_field_a_script_needs():
    findings, _ = diagnose_sim("errors", (), 30.0, "usb")
    doc = json.loads(to_json(findings))
    assert set(doc) == {"findings"} and doc["findings"]
    for x in doc["findings"]:
        assert {"kind", "severity", "link", "unit", "t_start", "t_end", "evidence", "frames", "statistic", "text",
                "action"} <= set(x)
        assert x["kind"] in {k.name for k in KINDS}


def test_findings_can_be_asked_again_as_frames_keep_coming():
    """The TUI asks while a capture runs: asking changes nothing, and later frames add to the same verdicts."""
    sc = apply(scenario_named("default"), ["unit_silent:5"])
    session = Session(CaptureSpec.of(), SimulatedSource(sc, sc.line, 20.0, 1, "usb"), [])
    session.open()
    engine = Diagnosis()
    engine.start_session(session)
    seen = []
    for i, f in enumerate(session):
        engine.frame(f)
        if i % 400 == 399:
            seen.append([x.kind for x in engine.findings() if x.severity == "error"])
    assert seen[-1] == ["unit_silent"] and [x.kind for x in engine.findings() if x.severity == "error"] == seen[-1]


# ------------------------------------------------------------------ the command
def test_command_text_and_json(tmp_path):
    cap = tmp_path / "late.mcap"
    r = run_sniffer("simulate", "--duration", "20", "--fault", "driver_enable_late:2", "--out", str(cap))
    assert r.returncode == 0, r.stderr
    r = run_sniffer("diagnose", str(cap))
    assert r.returncode == 0, r.stderr
    assert "ERROR   driver_enable_late  unit 2" in r.stdout and "do: " in r.stdout
    r = run_sniffer("diagnose", str(cap), "--format", "json")
    assert r.returncode == 0, r.stderr
    kinds = [(x["kind"], x["unit"]) for x in json.loads(r.stdout)["findings"]]
    assert kinds[0] == ("driver_enable_late", 2)


def test_command_bad_input_is_one_line_and_exit_2(tmp_path):
    r = run_sniffer("diagnose", str(tmp_path / "missing.mcap"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    cap = tmp_path / "c.mcap"
    assert run_sniffer("simulate", "--duration", "2", "--out", str(cap)).returncode == 0
    bad = tmp_path / "ref.csv"
    bad.write_text("name,value\nCn-02,60\n")
    r = run_sniffer("diagnose", str(cap), "--params", str(bad))
    assert r.returncode == 2 and "unit, register, value" in r.stderr and "Traceback" not in r.stderr
    r = run_sniffer("simulate", "--duration", "2", "--fault", "gremlins", "--out", str(cap))
    assert r.returncode == 2 and "unknown kind" in r.stderr
    r = run_sniffer("simulate", "--duration", "2", "--fault", "eeprom_wear:1", "--out", str(cap))
    assert r.returncode == 2 and "save register" in r.stderr  # the default scenario's drives have none


def test_check_holds_the_findings_in_the_golden(tmp_path, capsys):
    """`check --update-golden --findings` writes the verdicts after the frames; `check` then compares them
    (a verdict that appears or vanishes is a difference) whenever the golden holds them."""
    from sniffer.cli import main

    cap = tmp_path / "silent.mcap"
    assert main(["simulate", "--duration", "5", "--fault", "unit_silent:5", "--out", str(cap)]) == 0
    golden = tmp_path / "g.txt"
    assert main(["check", str(cap), "--golden", str(golden), "--update-golden", "--findings"]) == 0
    lines = golden.read_text().splitlines()
    assert "finding error unit_silent link=- unit=5" in lines and lines[-1].startswith("finding ")
    assert main(["check", str(cap), "--golden", str(golden)]) == 0  # held, and the same
    golden.write_text("\n".join(x.replace("unit=5", "unit=2") for x in lines) + "\n")
    capsys.readouterr()
    assert main(["check", str(cap), "--golden", str(golden)]) == 1
    out = capsys.readouterr().out
    assert "findings: 1 added (error unit_silent u5); 1 gone (error unit_silent u2)" in out
    assert main(["check", str(cap), "--golden", str(golden), "--diff"]) == 1
    out = capsys.readouterr().out
    assert "+finding error unit_silent link=- unit=5" in out and "-finding error unit_silent link=- unit=2" in out
    plain = tmp_path / "plain.txt"  # a golden without findings is compared as before
    assert main(["check", str(cap), "--golden", str(plain), "--update-golden"]) == 0
    assert not any(x.startswith("finding ") for x in plain.read_text().splitlines())
    assert main(["check", str(cap), "--golden", str(plain)]) == 0


def test_real_captures_of_healthy_lines_give_nothing_above_info():
    """The reference captures (sigrok-dumps: real masters and slaves on real lines) hold no fault to find."""
    import tomllib
    from pathlib import Path

    from sniffer.commands.replay import file_source

    root = Path(__file__).resolve().parent.parent / "captures"
    manifest = tomllib.loads((root / "manifest.toml").read_text())["capture"]
    entries = [e for e in manifest if e["about"].startswith("Real")]
    assert entries
    for e in entries:
        flags = e["flags"]
        spec = CaptureSpec.of(baud=int(flags[flags.index("--baud") + 1]),
                              parity=flags[flags.index("--parity") + 1] if "--parity" in flags else None,
                              stopbits=int(flags[flags.index("--stopbits") + 1]) if "--stopbits" in flags else None,
                              input=str(root / e["file"]), inputs=(str(root / e["file"]),))
        session = Session(spec, file_source(spec), [])
        session.open()
        engine = Diagnosis()
        engine.start_session(session)
        for f in session:
            engine.frame(f)
        assert worst(engine.findings()) == [], e["name"]


def test_docs_name_every_kind():
    from pathlib import Path

    doc = (Path(__file__).resolve().parent.parent / "docs" / "diagnose.md").read_text()
    for k in KINDS:
        assert f"| `{k.name}` |" in doc, k.name
    from sniffer.simulator.faults import KINDS as FAULTS

    for name in FAULTS:
        assert f"`{name}`" in doc, name


def test_demo_puts_a_fault_on_the_live_line(tmp_path):
    """`sniffer demo --fault`: the cause on a simulated bus captured live over a pty; its capture diagnosed."""
    out = tmp_path / "demo.mcap"
    r = run_sniffer("demo", "--fault", "unit_silent:5", "--duration", "4", "--headless", "--quiet", "--out", str(out),
                    timeout=180)
    assert r.returncode == 0, r.stderr
    assert "sniffer wrote 0 bytes to the bus" in r.stderr
    r = run_sniffer("diagnose", str(out), "--format", "json")
    assert r.returncode == 0, r.stderr
    assert ("unit_silent", 5) in [(x["kind"], x["unit"]) for x in json.loads(r.stdout)["findings"]]
    r = run_sniffer("demo", "--fault", "wrong_line_settings", "--duration", "1", "--headless", "--no-out")
    assert r.returncode == 2 and "simulate --fault wrong_line_settings" in r.stderr


def test_a_last_byte_cut_off_the_answer_as_a_flagged_byte_is_the_answers():
    """A framer that keeps a flagged byte out of a CRC-good frame leaves a cut answer a byte short (CRC bad)
    and the flagged byte right after it: still unit 2's last byte, and only unit 2's answers show it."""
    from sniffer.codes import Annotation
    from sniffer.framing.crc import crc_bytes
    from sniffer.events import CaptureInfo
    from sniffer.frame import Frame

    ms = 1_000_000
    engine = Diagnosis()
    engine.start(CaptureInfo(baud=19200, parity="E", stopbits=1), {"": CaptureSpec.of(baud=19200).resolve()}, {})
    index = 0

    def add(raw, role, unit, t, crc_ok=True, pair=None, protocol="modbus-rtu", ann=(), idle=None):
        nonlocal index
        f = Frame(index, t, t + len(raw) * 573_000, raw, protocol, unit, raw[1] if protocol != "noise" else None,
                  crc_ok=crc_ok if protocol != "noise" else None, idle_before_ns=idle)
        f.role, f.pair, f.adu = role, pair, raw[:-2]
        f.annotations = list(ann)
        index += 1
        engine.frame(f)
        return f

    t = 0
    for _ in range(40):
        for unit in (1, 2):
            req = bytes((unit, 3, 0x21, 0, 0, 2))
            r = add(req + crc_bytes(req), "request", unit, t)
            rsp = bytes((unit, 3, 4, 1, 2, 3, 4))
            rsp += crc_bytes(rsp)
            if unit == 2:
                a = add(rsp[:-1], "response", unit, t + 6 * ms, crc_ok=False, pair=r.index)
                add(rsp[-1:], "noise", None, a.t_end_ns, protocol="noise", idle=0,
                    ann=[Annotation("uart.framing_error", "error", "byte 0 flagged framing", 0, 1)])
            else:
                add(rsp, "response", unit, t + 6 * ms, pair=r.index)
            t += 20 * ms
    (f,) = [x for x in engine.findings() if x.severity != "info"]
    assert (f.kind, f.unit) == ("driver_disable_early", 2)


def test_params_against_an_earlier_capture(tmp_path):
    """--params CAPTURE: the last value of each parameter the earlier capture read; the same capture holds none
    changed, a reference that says otherwise makes the finding (through the command)."""
    from pathlib import Path

    from sniffer.diagnose.reference import load_capture

    cap = Path(__file__).resolve().parent.parent / "captures" / "sim" / "tds-v8.mcap"
    ref = load_capture(str(cap), CaptureSpec.of())
    values = {(u, name): v for _, u, name, v in ref.rows}
    assert values[(2, "An-01")] == 25.0 and values[(1, "Cn-02")] == 60.0
    r = run_sniffer("diagnose", str(cap), "--params", str(cap), "--format", "json")
    assert r.returncode == 0, r.stderr
    assert not [x for x in json.loads(r.stdout)["findings"] if x["kind"] == "params_changed"]
    csv = tmp_path / "saved.csv"
    csv.write_text("unit,register,value\n2,An-01,30.0\n")
    r = run_sniffer("diagnose", str(cap), "--params", str(csv), "--format", "json")
    (f,) = [x for x in json.loads(r.stdout)["findings"] if x["kind"] == "params_changed"]
    assert f["unit"] == 2 and f["evidence"]["changes"][0]["reference"] == 30.0


def test_retry_storm_and_the_notes_on_polling():
    """A unit that misses four answers in ten: the master's retries (to a unit that does answer) are a storm;
    a healthy line's notes: the cycle and the room left, and the reads whose answer never changes."""
    findings, _ = diagnose_sim("default", (), 30.0, "usb", params=("unit1.no_answer_prob=0.4",))
    (f,) = [x for x in findings if x.kind == "retry_storm"]
    assert f.severity == "warning" and f.unit is None and list(f.evidence["by_unit"]) == ["1"]
    assert not any(x.kind == "unit_silent" for x in findings)
    clean, _ = diagnose_sim("default", (), 30.0, "usb")
    (cycle,) = [x for x in clean if x.kind == "poll_cycle"]
    assert cycle.severity == "info" and cycle.evidence["units_polled"] == 3 and cycle.evidence["room_for_units"] >= 0
    fast, _ = diagnose_sim("fast", (), 30.0, "usb", 3)  # back-to-back polls: the discrete inputs, read often, stay put
    (redundant,) = [x for x in fast if x.kind == "poll_redundant"]
    assert redundant.severity == "info"
    reads = redundant.evidence["reads"]
    assert reads and all(v["per_s"] >= 1 and v["changes"] <= v["per_s"] * 30 / 100 for v in reads.values())


def test_driver_enable_times_of_a_logic_capture_make_the_finding():
    """A logic capture with the slave's DE line puts its timing on the frames (de_on_ns, de_off_ns): a driver
    that comes on a fraction of a bit late damages no byte yet, and the DE times alone say so."""
    from sniffer.framing.crc import crc_bytes
    from sniffer.events import CaptureInfo
    from sniffer.frame import Frame

    class DEFrame(Frame):
        __slots__ = ("de_on_ns", "de_off_ns")

    ms = 1_000_000
    engine = Diagnosis()
    engine.start(CaptureInfo(baud=19200, parity="E", stopbits=1), {"": CaptureSpec.of(baud=19200).resolve()}, {})
    t = 0
    for i in range(40):
        req = bytes((2, 3, 0x21, 0, 0, 2))
        r = DEFrame(2 * i, t, t + 4 * ms, req + crc_bytes(req), "modbus-rtu", 2, 3, crc_ok=True)
        r.role, r.adu, r.de_on_ns, r.de_off_ns = "request", req, None, None
        engine.frame(r)
        rsp = bytes((2, 3, 4, 1, 2, 3, 4))
        a = DEFrame(2 * i + 1, t + 6 * ms, t + 11 * ms, rsp + crc_bytes(rsp), "modbus-rtu", 2, 3, crc_ok=True)
        a.role, a.pair, a.adu = "response", r.index, rsp
        a.de_on_ns, a.de_off_ns = 20_000, 80_000  # on 20 us after the start bit began (0.4 bit), off well after
        engine.frame(a)
        t += 20 * ms
    (f,) = [x for x in engine.findings() if x.severity != "info"]
    assert (f.kind, f.unit) == ("driver_enable_late", 2)
    assert f.evidence["de_late"] == 40 and f.evidence["de_on_median_us"] == 20.0


@pytest.mark.parametrize("fault", ["noise_correlated_with_load:2", "drive_fault:2", "params_not_saved:2",
                                   "eeprom_wear:2"])
def test_a_fault_whose_verdict_needs_a_drive_model_is_refused_without_one(fault):
    """docs/diagnose.md: these kinds are judged from a drive model's registers; on a scenario of model-less drives
    the cause would be on the line and `diagnose` could never name it, so `simulate` says so instead."""
    from sniffer.simulator.faults import FaultError

    with pytest.raises(FaultError, match="real model"):
        apply(scenario_named("default"), [fault])
    apply(scenario_named("tds-v8"), [fault])  # a model scenario takes it


def test_the_fault_examples_in_simulate_help_run_on_its_default_scenario():
    """`simulate --help` names examples of --fault; each is one `simulate --out x.mcap --fault EXAMPLE` takes."""
    import re

    from sniffer.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "cmd")
    (fault,) = [a for a in sub.choices["simulate"]._actions if "--fault" in a.option_strings]
    examples = re.findall(r"\b([a-z_]+(?::\d+)?)(?=[,( ])", fault.help.split("e.g.", 1)[1].split("(", 1)[0] + " ")
    assert examples
    for example in examples:
        apply(scenario_named("default"), [example])


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_the_text_head_names_every_links_settings(tmp_path, capsys, jobs):
    """A capture of two links at different settings: the head says each link's, not the first link's alone."""
    from helpers import bursts, fr

    from sniffer.capture.session import EventSource
    from sniffer.cli import main
    from sniffer.events import CaptureInfo, Chunk
    from sniffer.formats import FileSink
    from sniffer.line import LineSettings

    a, b = LineSettings(19200, "E", 1), LineSettings(9600, "N", 2)
    events = []
    for link, line in (("drives", a), ("pumps", b)):
        for c in bursts([fr("010300000002"), fr("01030400010002")] * 20, line, gap_chars=40):
            events.append(Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link))
    events.sort(key=lambda c: c.t_ns)
    info = CaptureInfo(baud=a.baud, parity=a.parity, stopbits=a.stopbits, links=[
        {"name": "drives", "baud": a.baud, "parity": a.parity, "stopbits": a.stopbits},
        {"name": "pumps", "baud": b.baud, "parity": b.parity, "stopbits": b.stopbits}])
    cap = tmp_path / "links.mcap"
    Session(CaptureSpec(), EventSource(info, events), [FileSink("mcap", str(cap), timed_flush=False)]).run()
    capsys.readouterr()
    assert main(["diagnose", str(cap), "--jobs", jobs]) == 0
    head = capsys.readouterr().out.splitlines()[0]
    assert "drives" in head and "19200 8E1" in head and "pumps" in head and "9600 8N2" in head, head


def test_no_frame_read_is_not_said_to_be_a_healthy_line():
    from sniffer.diagnose import to_text

    assert "nothing on this line looks wrong" in to_text([], frames=5)
    text = to_text([], frames=0)
    assert "no frame was read" in text and "looks wrong" not in text


def test_a_request_timed_before_its_cycles_anchor_counts_in_the_first_twelfth():
    """Per-read times are estimated back from the read: a request may carry a time before the anchor request
    of its cycle.  The second-master test counts it at the cycle's start (it raised IndexError on a million
    frames of the stress scenario, in `diagnose` and in `report`)."""
    from collections import Counter

    from sniffer.diagnose import masters

    win = [(10_000, "A"), (0, "B"), (10_100, "A")] * 40
    phases = masters._phases(win, "A", Counter({"A": 100, "B": 100}))
    assert phases["B"][0] == 40  # every B counted once


def test_readings_of_a_running_drive_are_no_changed_parameters(tmp_path, capsys):
    """--params EARLIER.mcap holds what the map lets the master write; a monitor register (output frequency,
    current: access R) read at another value later is the drive working, not a changed parameter."""
    from sniffer.cli import main

    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    for path, seed in ((a, "1"), (b, "2")):
        assert main(["simulate", "--scenario", "tds-v8", "--duration", "20", "--seed", seed, "--out", str(path)]) == 0
    capsys.readouterr()
    main(["diagnose", str(b), "--params", str(a), "--jobs", "1", "--format", "json"])
    findings = json.loads(capsys.readouterr().out)["findings"]
    changed = [x for x in findings if x["kind"] == "params_changed"]
    assert not changed, changed


@pytest.mark.parametrize("scenario, faults", [("errors", []), ("default", ["--fault", "second_master_blind:2"])])
def test_damage_no_rule_explains_is_still_said(tmp_path, capsys, scenario, faults):
    """A line whose frames are damaged by something no kind recognises is not "nothing to report": line_damage
    says how much, when, and whose answers carry it."""
    from sniffer.cli import main

    cap = tmp_path / "x.mcap"
    assert main(["simulate", "--scenario", scenario, "--duration", "40", *faults, "--out", str(cap)]) == 0
    capsys.readouterr()
    main(["diagnose", str(cap), "--jobs", "1", "--format", "json"])
    findings = json.loads(capsys.readouterr().out)["findings"]
    assert [f["kind"] for f in findings if f["severity"] != "info"], findings  # never silent about it
    damage = [f for f in findings if f["kind"] == "line_damage"]
    causes = {"second_master", "bus_unbiased", "driver_enable_late", "driver_disable_early"}
    if not any(f["kind"] in causes for f in findings):
        (f,) = damage
        assert f["severity"] == "warning" and f["evidence"]["damaged"] >= 10 and f["episodes"]


def test_a_healthy_line_has_no_line_damage(tmp_path, capsys):
    from sniffer.cli import main

    cap = tmp_path / "x.mcap"
    assert main(["simulate", "--scenario", "stress", "--duration", "20", "--out", str(cap)]) == 0
    capsys.readouterr()
    main(["diagnose", str(cap), "--jobs", "1", "--format", "json"])
    assert not [f for f in json.loads(capsys.readouterr().out)["findings"] if f["kind"] == "line_damage"]


def test_a_params_csv_without_its_header_says_what_a_params_file_is(tmp_path, capsys):
    from pathlib import Path

    from sniffer.cli import main

    root = Path(__file__).resolve().parent.parent
    bad = tmp_path / "p.csv"
    bad.write_text("2,Cn-02,60\n1,Cn-02,50\n")
    assert main(["diagnose", str(root / "captures" / "sim" / "tds-v8.mcap"), "--params", str(bad), "--jobs", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "neither a parameter CSV (a header line with the columns unit, register, value)" in err[0]
