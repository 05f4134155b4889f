"""The PD-series line on the simulated bus, through the real pipeline, judged against the ground truth.

The simulator plays a PLC and two PD-series inverters (pd_master.py,
pd_drive.py) from the decoder's own schema; the sniffer frames them with the
PD framers (pd-rtu, pd-ascii) and decodes them with `pd-series`.  What must
hold: the > 50 ms quiet time before every frame, every frame back byte for
byte in order (logic analyzer and USB adapter views), requests and replies
paired, status values with the manual's names and Hz, error replies 81H/83H
as exceptions, and no warnings or errors except on the PLC's deliberate
mistakes.
"""

from __future__ import annotations

from collections import Counter

import pytest
from helpers import demo_records, simulate_and_decode

from decoders.pd_series.schema import CNTR_BITS, PARAMS, STATUS
from sniffer.line import LineSettings
from sniffer.framing.pd import QUIET_NS
from sniffer.simulator import (
    KIND_BROADCAST,
    KIND_EXCEPTION,
    KIND_REQUEST,
    KIND_RESPONSE,
    get_scenario,
    simulate,
)
from sniffer.simulator.pd_drive import LAST_PARAM, PD, data_method, status_scale
from sniffer.simulator.pd_master import cntr

PD_SCENARIOS = ["pd-series", "pd-series-ascii"]
DEVICES = {1: "pd-series", 2: "pd-series", 0: "pd-series"}
SECONDS = 30.0
PROTOCOL = {"pd-series": "pd-rtu", "pd-series-ascii": "pd-ascii"}

def run(name: str, adapter: str = "wire", seed: int = 1):
    return simulate_and_decode(name, SECONDS, adapter, seed, devices=DEVICES, protocol=PROTOCOL[name])


def adu(f) -> bytes:
    """ADDR FUNC LEN DATA of a simulated frame (RTU: drop the CRC; ASCII: unhex, drop the LRC)."""
    if f.raw.startswith(b":"):
        return bytes.fromhex(f.raw[1:-2].decode())[:-1]
    return f.raw[:-2]


def mistake(sent, i: int) -> bool:
    """The PLC's deliberate mistakes: requests that draw 81H/83H, and those replies."""
    f = sent[i]
    if f.kind == KIND_EXCEPTION:
        return True
    return f.kind == KIND_REQUEST and i + 1 < len(sent) and sent[i + 1].kind == KIND_EXCEPTION


# ------------------------------------------------------------------ the data


def test_scenarios_say_line_protocol_devices_and_quiet_time():
    for name in PD_SCENARIOS:
        sc = get_scenario(name)
        assert sc.protocol == PROTOCOL[name]
        assert sc.devices == DEVICES  # the demo decodes the broadcasts (unit 0) with the model too
        assert sc.quiet_ms * 1e6 == QUIET_NS
        assert {u.unit for u in sc.units} == {1, 2}
        assert data_method(name.endswith("-ascii"), sc.line.parity) is not None  # PD165 can say the line


def test_profile_codes_every_status_value_of_the_schema():
    assert {STATUS[c].label for c in STATUS} == set(PD.status)
    assert status_scale("Set F") == status_scale("Out F") == STATUS[0].scale == 0.01


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_frames_follow_the_len_rule_and_the_quiet_time(name):
    sc, sent, _ = run(name)
    prev_end = None
    for f in sent:
        a = adu(f)
        assert a[2] == len(a) - 3, f  # LEN counts the bytes between LEN and the check
        assert a[0] == f.unit and a[1] == f.function
        if prev_end is not None:
            assert f.t_ns - prev_end > QUIET_NS  # "the time of no data is more than 50 ms" (l.205)
        prev_end = f.t_end_ns
    kinds = Counter(f.kind for f in sent)
    assert kinds[KIND_REQUEST] == kinds[KIND_RESPONSE] + kinds[KIND_EXCEPTION]  # every unit answers
    assert kinds[KIND_BROADCAST] >= 2 and kinds[KIND_EXCEPTION] >= 3
    assert {f.function for f in sent} >= {0x01, 0x02, 0x03, 0x04, 0x05, 0x08, 0x81, 0x83}


def test_same_seed_same_line():
    sc = get_scenario("pd-series")
    a = list(simulate(sc, sc.line, 5.0, seed=3))
    b = list(simulate(sc, sc.line, 5.0, seed=3))
    c = list(simulate(sc, sc.line, 5.0, seed=4))
    assert a == b and [f.raw for f in a] != [f.raw for f in c]


def test_drive_answers_as_the_manual_says():
    import random

    from decoders.pd_series.schema import CNST_BITS
    from sniffer.simulator import UnitSpec
    from sniffer.simulator.pd_drive import PdDrive, pdu

    cnst = {b.name: b.bit for b in CNST_BITS}
    d = PdDrive(UnitSpec(1, rated_current_a=7.0), random.Random(1), method=3)

    def on(reply: bytes) -> set[str]:
        return {n for n, bit in cnst.items() if reply[2] >> bit & 1}

    assert d.handle(pdu(0x01, bytes((165, 0, 0)))) == pdu(0x01, bytes((165, 3)))  # byte-wide: LEN=2
    assert d.handle(pdu(0x01, bytes((174, 0, 0)))) == pdu(0x01, bytes((174, 0, 7)))  # rated current, a word
    assert d.handle(pdu(0x01, bytes((LAST_PARAM + 1, 0, 0)))) == pdu(0x81, bytes((LAST_PARAM + 1,)))
    assert d.handle(pdu(0x02, bytes((174, 0, 9)))) == pdu(0x81, bytes((174,)))  # read only (l.291)
    assert d.handle(pdu(0x02, bytes((170, 6)))) == pdu(0x81, bytes((170,)))  # set range 0-5
    assert d.handle(w := pdu(0x02, bytes((3, 0x0B, 0xB8)))) == w and d.setpoint_hz == 30.0  # the l.189 value
    assert on(d.handle(pdu(0x03, bytes((cntr("run+forward"),))))) == {"run", "running"}
    d.advance(0)
    d.advance(4_000_000_000)  # 5 s to 50 Hz
    assert d.status_value(1) == d.status_value(0) == 3000  # Out F reached Set F: 30.00 Hz
    assert on(d.handle(pdu(0x03, bytes((cntr("r_f"),))))) == {"run", "running", "r_f_command", "r_f_running"}
    assert d.handle(pdu(0x03, bytes((cntr("run+stop"),))))[:2] == bytes((0x83, 1))  # contradictory
    assert on(d.handle(pdu(0x03, bytes((cntr("stop"),))))) >= {"running", "braking"}  # ramping down
    d.advance(14_000_000_000)
    assert on(d.handle(pdu(0x03, bytes((cntr("jog+jog_forward"),))))) == {"jog", "jogging"}
    d.advance(16_000_000_000)
    assert d.status_value(1) == round(PD.jog_hz * 100)


# -------------------------------------------------------------- the wire


@pytest.mark.parametrize("adapter", ["wire", "usb"])
@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_every_simulated_frame_recovered_and_paired(name, adapter):
    sc, sent, got = run(name, adapter)
    assert [g.raw for g in got] == [f.raw for f in sent]  # byte for byte, in order, nothing split or glued
    assert all(g.protocol == PROTOCOL[name] and g.crc_ok for g in got)
    for i, (f, g) in enumerate(zip(sent, got)):
        assert g.unit == f.unit and g.adu == adu(f)
        if f.kind == KIND_BROADCAST:
            assert g.role == "request" and g.pair is None and g.unit == 0
        elif f.kind == KIND_REQUEST:
            assert g.role == "request" and g.pair == got[i + 1].index, (i, g.summary)
        else:
            assert g.role == "response" and g.pair == got[i - 1].index, (i, g.summary)


@pytest.mark.parametrize("adapter", ["wire", "usb"])
@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_no_warnings_or_errors_on_clean_frames(name, adapter):
    sc, sent, got = run(name, adapter)
    expected = Counter()
    for i, (f, g) in enumerate(zip(sent, got)):
        codes = {a.code for a in g.annotations}
        if not mistake(sent, i):
            bad = [(a.code, a.detail) for a in g.annotations if a.severity in ("warning", "error")]
            assert not bad, (i, g.summary, bad)
            assert "pd.timing.quiet" not in codes and "pd.len.mismatch" not in codes
            assert codes <= {"pair.broadcast"}, (i, g.summary, codes)
            assert (f.kind == KIND_BROADCAST) == ("pair.broadcast" in codes)
        else:
            expected.update(codes)
    assert expected["pd.error.reply"] == sum(f.kind == KIND_EXCEPTION for f in sent)


# ------------------------------------------------------------ the decode


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_status_values_have_names_units_and_evolve(name):
    sc, sent, got = run(name)
    seen: dict[int, dict[str, list]] = {1: {}, 2: {}}
    commanded: dict[int, set[float]] = {1: set(), 2: set()}  # set frequencies written (05H, PD003, broadcast)
    for g in got:
        if g.role == "request" and g.function in (0x02, 0x05) and g.points and g.points[0]["unit"] == "Hz":
            for u in ([g.unit] if g.unit else [1, 2]):
                commanded[u].add(g.points[0]["value"])
        if g.role == "response" and g.function == 0x04:
            (pt,) = g.points
            cfg = g.adu[3]
            st = STATUS[cfg]
            assert pt["name"] == st.label and pt["raw"] == int.from_bytes(g.adu[4:6], "big")
            if st.unit == "Hz":
                assert pt["unit"] == "Hz" and pt["value"] == pytest.approx(pt["raw"] * 0.01)
                assert f"{st.label} = " in g.summary and g.summary.endswith(" Hz")
            else:
                assert "scale not given by the manual" in pt["text"]
            seen[g.unit].setdefault(st.label, []).append(pt["raw"] * status_scale(st.label))
    for unit, vals in seen.items():
        assert set(vals) == {s.label for s in STATUS.values()}, unit  # every CFG polled
        out_f = vals["Out F"]
        assert out_f[0] == 0.0 and max(out_f) > 10.0  # ramps up from standstill
        assert all(any(abs(v - c) < 0.01 for c in commanded[unit]) for v in vals["Set F"])
        assert max(out_f) <= max(commanded[unit]) + 1e-6  # ramps toward the set frequency, never past it
        assert sum(any(abs(v - s) < 0.01 for s in commanded[unit]) for v in out_f) > 5  # and reaches it
        assert max(vals["Out A"]) > 0  # current with load
        assert all(280.0 < v < 400.0 for v in vals["DCV"])  # 220 V class: ~311 V DC bus
        assert vals["Cont"] == sorted(vals["Cont"])  # a counter only counts up


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_parameters_read_and_written_by_the_manuals_ids(name):
    sc, sent, got = run(name)
    reads = {g.points[0]["id"]: g.points[0] for g in got
             if g.role == "response" and g.function == 0x01 and g.points}
    assert reads["PD174"]["unit"] == "A" and reads["PD174"]["value"] in {round(u.rated_current_a) for u in sc.units}
    assert reads["PD176"]["text"] == "50 Hz"
    assert reads["PD003"]["unit"] == "Hz"
    ascii_mode = name.endswith("-ascii")
    assert reads["PD165"]["value"] == data_method(ascii_mode, sc.line.parity)
    assert reads["PD165"]["text"] == f"8{sc.line.parity}1 for {'ASCII' if ascii_mode else 'RTU'}"
    writes = [g for g in got if g.role == "response" and g.function == 0x02 and g.unit != 0]
    assert {g.points[0]["id"] for g in writes} >= {"PD003", "PD172"}
    assert PARAMS[172].running  # the PLC writes PD172 while the drives run: allowed (l.335 "**")


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_error_replies_are_exceptions_paired_with_their_request(name):
    sc, sent, got = run(name)
    kinds = Counter()
    for i, g in enumerate(got):
        if sent[i].kind != KIND_EXCEPTION:
            assert g.exception is None
            continue
        req = got[i - 1]
        assert g.exception["code"] == sent[i].exception_code == g.adu[1]
        assert "pd.error.reply" in {a.code for a in g.annotations}
        if g.adu[1] == 0x81 and req.function == 0x01:
            kinds["read"] += 1
            assert req.adu[3] > LAST_PARAM and f"PD{req.adu[3]:03d}" in g.summary
        elif g.adu[1] == 0x81:
            kinds["write"] += 1
            assert req.function == 0x02 and g.function == 0x82  # paired as 82H (l.123-125)
            assert {"pd.value.range", "pd.error.write"} <= {a.code for a in req.annotations + g.annotations}
        else:
            kinds["control"] += 1
            assert req.function == 0x03 and req.adu[3] == cntr("forward+reverse")
            assert g.points[0]["name"] == "CNST"
    assert kinds["read"] and kinds["write"] and kinds["control"], kinds


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_control_commands_and_status_bits(name):
    sc, sent, got = run(name)
    labels = {b.name: b.label for b in CNTR_BITS}
    commands = set()
    for i, g in enumerate(got):
        if g.function != 0x03:
            continue
        (pt,) = g.points
        if g.role == "request":
            commands.add(pt["text"])
        elif got[i - 1].points[0]["text"] == f"{labels['run']} {labels['forward']}":
            assert pt["text"].startswith("run") and "running" in pt["text"]  # CNST: run, running
        elif got[i - 1].points[0]["text"] == labels["stop"]:
            assert "run" not in pt["text"].split()  # run command off; maybe still running + braking
    assert {"run for", "stop"} <= commands


@pytest.mark.parametrize("name", PD_SCENARIOS)
def test_broadcasts_get_no_reply(name):
    sc, sent, got = run(name)
    bc = [i for i, f in enumerate(sent) if f.kind == KIND_BROADCAST]
    assert bc
    for i in bc:
        assert got[i].unit == 0 and got[i].function in (0x02, 0x05) and "(broadcast)" in got[i].summary
        if i + 1 < len(got):
            assert got[i + 1].role == "request" and got[i + 1].function != got[i].function


# ------------------------------------------------------------ the commands


def test_demo_plays_the_pd_line_live(tmp_path):
    recs, _out = demo_records(tmp_path, "pd-series")
    assert all(rec["crc_ok"] and rec["protocol"] == "pd-rtu" and rec["model"] == "pd-series" for rec in recs)
    assert any(p["name"] == "Out F" and p["unit"] == "Hz" for rec in recs for p in rec["points"])


def test_other_lines_keep_the_quiet_time():
    sc = get_scenario("pd-series-ascii")
    line = LineSettings(19200, "E", 1)
    frames = list(simulate(sc, line, 5.0, seed=2))
    assert all(b.t_ns - a.t_end_ns > QUIET_NS for a, b in zip(frames, frames[1:]))
