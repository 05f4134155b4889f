"""Every drive model on the simulated bus, through the real pipeline, judged against the ground truth.

The simulator plays each model as its manual describes it (profiles.py +
the model's register map); the sniffer decodes it with the same map.  What
must hold: every frame comes back byte for byte (logic analyzer and USB
adapter views, RTU and ASCII), values carry the manual's names and units,
injected faults read as the model's fault text and clear after a reset,
vendor exceptions carry the model's names, and the TDS-V8 DRV-mode Cn
write is flagged.
"""

from __future__ import annotations

import json
from binascii import unhexlify

import pytest
from helpers import demo_records, run_sniffer, simulate_and_decode

from decoders.registry import default_registry
from sniffer.framing.crc import lrc
from sniffer.simulator import (
    KIND_EXCEPTION,
    KIND_REQUEST,
    KIND_RESPONSE,
    PROFILES,
    SCENARIOS,
    get_model,
    get_scenario,
)

MODEL_SCENARIOS = ["tds-v8", "a510", "a510-ascii", "spl", "spl-ascii"]
# exception codes each scenario must show in 10 s (the model's own ones, from its map)
MUST_RAISE = {
    "tds-v8": {0x03, 0x21},  # 03H: the Cn write in DRV mode; 21H: busy right after an EEPROM save
    "a510": {0x04},  # "Register number is over 32"
    "a510-ascii": {0x04},
    "spl": {0x51, 0x52, 0x53, 0x54, 0x55},
    "spl-ascii": {0x51, 0x52, 0x53, 0x54, 0x55},
}
SECONDS = 10.0

def run(name: str, adapter: str = "wire", seed: int = 1):
    return simulate_and_decode(name, SECONDS, adapter, seed)


def codes_of(f) -> list[str]:
    return [a.code for a in f.annotations]


def monitor_responses(name: str, unit: int | None = None):
    """Decoded replies to the PLC's poll of the model's monitor block."""
    sc, _, got = run(name)
    first = PROFILES[sc.devices[1]].monitor[0]
    return [f for f in got if f.role == "response" and f.points and f.points[0]["address"] == first
            and (unit is None or f.unit == unit)]


# ------------------------------------------------------------------ the data


def test_scenarios_say_line_protocol_and_models():
    for name in MODEL_SCENARIOS:
        sc = get_scenario(name)
        assert sc.protocol == ("modbus-ascii" if name.endswith("-ascii") else "modbus-rtu")
        assert set(sc.devices) == {u.unit for u in sc.units}
        assert set(sc.devices.values()) == {name.removesuffix("-ascii")}
        assert default_registry(sc.devices).devices == sc.devices  # the sniffer knows the models
        if sc.protocol == "modbus-ascii":
            assert sc.line.databits == 7
    for name in ("default", "errors", "fast", "stress"):
        sc = SCENARIOS[name]
        assert sc.devices == {} and sc.protocol == "modbus-rtu"
    assert get_scenario("tds-v8").line.baud in get_model("tds-v8").map.model.bauds


@pytest.mark.parametrize("model", sorted(PROFILES))
def test_profiles_name_registers_the_map_has(model):
    m = get_model(model)  # raises if an address, fault mnemonic or exception code is not in the map
    regs = m.map.registers
    p = m.profile
    assert regs[p.command].access == regs[p.frequency].access == "RW"
    first, count = p.monitor
    assert count <= (m.max_regs or 125)
    for addr in (p.status, *p.fault, *p.quantities):
        assert first <= addr < first + count and regs[addr].access == "R"
    assert len(m.trips) == len(p.trips) and all(t.label for t in m.trips)


# -------------------------------------------------------------- the wire


@pytest.mark.parametrize("adapter", ["wire", "usb"])
@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_every_simulated_frame_recovered_and_paired(name, adapter):
    sc, sent, got = run(name, adapter)
    assert len(sent) > 150
    assert [f.raw for f in got] == [f.raw for f in sent]
    for i, (s, g) in enumerate(zip(sent, got)):
        assert g.crc_ok and g.protocol == sc.protocol and g.model == sc.devices[s.unit]
        assert g.role == ("request" if s.kind == KIND_REQUEST else "response")
        if s.kind in (KIND_RESPONSE, KIND_EXCEPTION):
            assert s.txn == sent[i - 1].txn and g.pair == got[i - 1].index  # paired with its own request


@pytest.mark.parametrize("name", ["a510-ascii", "spl-ascii"])
def test_ascii_frames_are_colon_hex_lrc_crlf(name):
    _, sent, got = run(name)
    for s, g in zip(sent, got):
        assert s.raw.startswith(b":") and s.raw.endswith(b"\r\n") and s.raw[1:-2] == s.raw[1:-2].upper()
        binary = unhexlify(s.raw[1:-2])
        assert lrc(binary[:-1]) == binary[-1]  # two's complement of the byte sum
        assert g.adu == binary[:-1] and (g.unit, g.function) == (s.unit, s.function)


# ---------------------------------------------------------- what it means


@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_monitor_points_carry_the_manuals_names_and_units(name):
    sc, _, got = run(name)
    m = get_model(sc.devices[1])
    roles = {what: addr for addr, what in m.profile.quantities.items()}
    rsps = monitor_responses(name)
    assert len(rsps) > 20
    for f in rsps:
        for pt in f.points:
            r = m.map.registers[pt["address"]]
            assert pt["name"] == r.name and (pt["id"] or "") == r.id
            assert pt["unit"] == (r.unit or None) and not pt.get("pending")
    out = [{p["address"]: p for p in f.points} for f in rsps]
    hz = [o[roles["out_hz"]]["value"] for o in out]
    assert all(0 <= v <= m.max_hz(m.params) for v in hz) and len(set(hz)) > 5  # it ramps
    assert any(v > 5 and v == o[roles["freq_cmd"]]["value"] for v, o in zip(hz, out))  # reaches its setpoint
    dc = [o[roles["dc_bus"]]["value"] for o in out]
    assert all(abs(v - 1.35 * m.profile.supply_v) < 0.15 * 1.35 * m.profile.supply_v for v in dc)
    assert all(o[roles["current"]]["value"] > 0 for o, v in zip(out, hz) if v > 1)  # load current
    assert all(o[roles["current"]]["value"] == 0 for o, v in zip(out, hz) if v == 0)


def test_a510_output_frequency_in_hz():
    for name in ("a510", "a510-ascii"):
        pts = [p for f in monitor_responses(name) for p in f.points if p["address"] == 0x2524]
        assert pts and all(p["name"] == "Output frequency" and p["unit"] == "Hz" for p in pts)


def test_tds_reads_cn02_first_so_frequencies_are_in_hz():
    _, _, got = run("tds-v8")
    first_rsp = got[1]
    assert first_rsp.points[0]["id"] == "Cn-02" and first_rsp.points[0]["value"] == 60.0
    assert not any("model.scale.pending" in codes_of(f) for f in got)
    freq = [p for f in got for p in f.points if p["address"] in (0x0001, 0x0024, 0x0025)]
    assert freq and all(p["unit"] == "Hz" for p in freq)
    writes = [p["value"] for f in got if f.role == "request" and f.function in (0x06, 0x10)
              for p in f.points if p["address"] == 0x0001]
    assert writes and all(10.0 <= v <= 60.0 for v in writes)  # the operator's setpoints, in Hz


@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_injected_fault_shows_as_fault_text_and_clears_after_reset(name):
    sc, _, got = run(name)
    m = get_model(sc.devices[1])
    p = m.profile
    labels = {t.label for t in m.trips}
    fault_bit = 1 << p.status_bits["fault"]
    rsps = monitor_responses(name, unit=1)

    def faults(f):
        return [pt for pt in f.points if pt["address"] in p.fault and pt["raw"]]

    def status(f):
        return next(pt["raw"] for pt in f.points if pt["address"] == p.status)

    k = next(i for i, f in enumerate(rsps) if faults(f))  # unit 1 trips within 3-7 s
    tripped = rsps[k]
    assert [pt["text"] for pt in faults(tripped)][0] in labels
    assert status(tripped) & fault_bit
    reset_bit = 1 << p.command_bits["reset"]
    reset = next(f for f in got if f.role == "request" and f.unit == 1 and f.t_ns > tripped.t_ns
                 and any(pt["address"] == p.command and pt["raw"] & reset_bit for pt in f.points))
    after = [f for f in rsps if f.t_ns > reset.t_ns]
    assert after and not faults(after[0]) and not status(after[0]) & fault_bit
    assert all(status(f) & fault_bit for f in rsps[k:] if f.t_ns < reset.t_ns)  # latched until the reset


@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_exceptions_decode_with_the_models_names(name):
    sc, sent, got = run(name)
    m = get_model(sc.devices[1])
    truth = [s.exception_code for s in sent if s.kind == KIND_EXCEPTION]
    seen = [f for f in got if f.exception]
    assert [f.exception["code"] for f in seen] == truth
    assert MUST_RAISE[name] <= set(truth)
    for f in seen:
        code = f.exception["code"]
        assert f.exception["name"] == m.map.exceptions[code]["name"]
        assert ("model.exception.vendor" in codes_of(f)) == (code > 0x0B)


def test_tds_cn_write_in_drv_mode_is_flagged():
    sc, sent, got = run("tds-v8")
    m = get_model("tds-v8")
    (lo, hi), = m.prg_only
    cn_writes = [i for i, s in enumerate(sent) if s.kind == KIND_REQUEST and s.function == 0x06
                 and lo <= int.from_bytes(s.raw[2:4], "big") <= hi]
    flagged = [i for i, f in enumerate(got) if "tds.write.prg_only" in codes_of(f)]
    assert cn_writes and flagged == cn_writes
    for i in flagged:
        assert got[i].points[0]["id"] == "Cn-27"
        assert got[i + 1].exception["code"] == m.profile.exceptions["mode"]  # the drive refuses it


# ------------------------------------------------------------ the commands


def test_simulate_writes_models_and_protocol_so_replay_needs_no_flags(tmp_path):
    out = tmp_path / "spl.mcap"
    r = run_sniffer("simulate", "--scenario", "spl-ascii", "--duration", "4", "--out", str(out))
    assert r.returncode == 0, r.stderr
    from sniffer.formats.mcap.reader import open_mcap

    info, _ = open_mcap(out)
    assert (info.protocol, info.devices, info.databits) == ("modbus-ascii", {1: "spl", 2: "spl"}, 7)
    r = run_sniffer("replay", str(out), "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    recs = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(recs) > 50
    assert all(rec["crc_ok"] and rec["protocol"] == "modbus-ascii" and rec["model"] == "spl" for rec in recs)
    names = {p["name"] for rec in recs for p in rec["points"]}
    assert {"Output frequency", "Error content"} <= names


def test_demo_plays_a_model_scenario_live(tmp_path):
    recs, out = demo_records(tmp_path, "a510-ascii")
    assert all(rec["crc_ok"] and rec["protocol"] == "modbus-ascii" and rec["model"] == "a510" for rec in recs)
    from sniffer.formats.mcap.reader import open_mcap

    info, _ = open_mcap(out)
    assert info.protocol == "modbus-ascii" and info.devices == {1: "a510", 2: "a510"}
