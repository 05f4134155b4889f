"""`sniffer learn CAPTURE --out map.toml`: a skeleton map from traffic that loads and decodes the capture.

A synthetic meter (written here as a byte CSV, as a logic analyzer would give it) carries known
types: float32 pairs in both word orders, a signed value, a rising counter, a constant and a u32
counter whose high word steps when the low word wraps; learn must guess each with its evidence.
The simulated bus and a real flow meter (sigrok-dumps, captures/refcaptures) show the rest.
"""

from __future__ import annotations

import json
import math
import random
import struct

import pytest

from decoders.tables import load_map
from sniffer.cli import main
from sniffer.framing.crc import crc_bytes
from sniffer.analysis.learn import Learner, RegStats, guess_pair, guess_word
from tests.test_bad_input import cli, one_error

SIM = "captures/sim/default.mcap"
FLOW = "captures/refcaptures/sigrok/flowmeter_target_15liter_per_min.bytes.csv"


def _frame(body: bytes) -> bytes:
    return body + crc_bytes(body)


def _words_f(x: float, order: str = "big") -> list[int]:
    hi, lo = struct.unpack(">HH", struct.pack(">f", x))
    return [hi, lo] if order == "big" else [lo, hi]


def _polls_capture(path, blocks_of, polls: int = 40, seed: int = 5) -> None:
    """A unit-7 byte CSV at 9600 8N1: each poll reads every (fc, start, words) `blocks_of(rng)` gives."""
    rng = random.Random(seed)
    char_s = 11 / 9600
    rows, t = [], 0.0
    for _ in range(polls):
        for fc, start, words in blocks_of(rng):
            req = _frame(bytes([7, fc]) + struct.pack(">HH", start, len(words)))
            rsp = _frame(bytes([7, fc, 2 * len(words)]) + struct.pack(f">{len(words)}H", *words))
            for data, gap in ((req, 0.004), (rsp, 0.05)):
                for b in data:
                    rows.append(f"{t:.6f},RX,{b:02x},")
                    t += char_s
                t += gap
    path.write_text("t_s,channel,byte_hex,flags\n" + "\n".join(rows) + "\n")


def meter_capture(path, polls: int = 60, seed: int = 3) -> dict:
    """A meter at unit 7, 9600 8N1: fc04 0..9 (five float32s, the last one low word first) and fc03
    0x100..0x104 (s16, rising counter, constant, u32 counter); a byte CSV at `path`.  The truth, by address."""
    state = {"energy": 65_400, "count": 10}

    def blocks(rng):
        floats = [230 + rng.uniform(-3, 3), rng.uniform(0.5, 12.0), 50 + rng.uniform(-0.05, 0.05),
                  rng.uniform(100, 2500), rng.uniform(0.85, 0.99)]
        inputs = [w for x in floats[:4] for w in _words_f(x)] + _words_f(floats[4], "little")
        state["energy"] += rng.randint(20, 60)
        state["count"] += rng.randint(1, 3)
        energy = state["energy"]
        holding = [rng.randint(-40, 40) & 0xFFFF, state["count"], 1234, energy >> 16, energy & 0xFFFF]
        return [(4, 0, inputs), (3, 0x100, holding)]

    _polls_capture(path, blocks, polls, seed)
    return {0: ("f32", "big"), 2: ("f32", "big"), 4: ("f32", "big"), 6: ("f32", "big"),
            8: ("f32", "little"), 0x100: ("s16", "big"), 0x101: ("u16", "big"), 0x102: ("u16", "big"),
            0x103: ("u32", "big")}


def _learn(capsys, capture, out, *flags) -> tuple[int, str]:
    code = main(["learn", str(capture), "--out", str(out), *flags])
    return code, capsys.readouterr().err


def _replay(capsys, capture, model_file, devices, *flags) -> list[dict]:
    args = ["replay", str(capture), "--model-file", str(model_file), "--format", "jsonl", *flags]
    for d in devices:
        args += ["--device", d]
    code = main(args)
    out, err = capsys.readouterr()
    assert code == 0, err
    return [json.loads(line) for line in out.splitlines()]


def test_learn_synthetic_meter_guesses_types_with_evidence(tmp_path, capsys):
    cap = tmp_path / "meter.csv"
    truth = meter_capture(cap)
    out = tmp_path / "meter7.toml"
    code, err = _learn(capsys, cap, out, "--baud", "9600")
    assert code == 0, err
    m = load_map(out)
    assert m.model_id == "meter7"
    rows = {**m.inputs, **m.registers}  # fc04 rows are table "input", fc03 rows "holding"
    assert {r.table for r in m.inputs.values()} == {"input"} and {r.table for r in m.registers.values()} == {"holding"}
    got = {a: (r.type, r.word_order) for a, r in rows.items()}
    assert got == truth
    notes = {a: r.note for a, r in rows.items()}
    assert "float32 (high word first) 227." in notes[0] and "low word jumps" in notes[0]
    assert "float32 (low word first) 0.8" in notes[8]
    assert "signed: -" in notes[0x100] and "as s16" in notes[0x100]
    assert "rising (a counter?)" in notes[0x101]
    assert "constant 1234 (0x04D2) in 60 values" in notes[0x102]
    assert "counter: as u32" in notes[0x103] and "wraps" in notes[0x103]
    assert all(r.access == "R" for r in rows.values())
    text = out.read_text()
    assert "u7 fc04 read input 0000H..0009H (10): 60x, every" in text
    assert "u7 fc03 read holding 0100H..0104H (5): 60x, every" in text
    # the skeleton loads with --model-file and decodes the same capture with its names
    recs = _replay(capsys, cap, out, ["7=meter7"], "--baud", "9600")
    names = {p["name"] for r in recs for p in r["points"]}
    assert {"input 0000H", "input 0008H", "holding 0100H", "holding 0102H", "holding 0103H"} <= names
    assert {r["model"] for r in recs if r["unit"] == 7} == {"meter7"}
    const = [p["value"] for r in recs for p in r["points"] if p["name"] == "holding 0102H"]
    assert const == [1234] * 60
    signed = [p["value"] for r in recs for p in r["points"] if p["name"] == "holding 0100H"]
    assert len(signed) == 60 and min(signed) < 0 <= max(signed) <= 40


def test_learn_simulated_bus_ranges_match_the_traffic(tmp_path, capsys):
    out = tmp_path / "drives.toml"
    code, err = _learn(capsys, SIM, out)
    assert code == 0, err
    assert f"wrote {out}: 3 units" in err
    m = load_map(out)
    text = out.read_text()
    for unit in (1, 2, 5):
        assert f"u{unit} fc03 read holding 2100H..2107H (8)" in text
        assert f"u{unit} fc10 write holding 2000H..2001H (2)" in text
    # every register read on the bus has a row, and its note gives each unit's range as the frames carried it
    recs = _replay(capsys, SIM, out, [f"{u}=drives" for u in (1, 2, 5)])
    seen: dict[tuple[int, int, int], list[int]] = {}
    for r in recs:
        if r["crc_ok"] and r["role"] == "response" and r["function"] in (3, 4):
            for p in r["points"]:
                seen.setdefault((r["unit"], r["function"], p["address"]), []).append(p["raw"])
    assert {a for _u, fc, a in seen if fc == 3} == set(m.registers)
    assert {a for _u, fc, a in seen if fc == 4} == set(m.inputs)
    for (unit, fc, a), vals in seen.items():
        if a == 0x2001:  # read and written: the note counts both
            continue
        note = (m.inputs if fc == 4 else m.registers)[a].note
        lo, hi = min(vals), max(vals)
        assert (f"constant {lo} " in note) if lo == hi else (f"{lo}..{hi}" in note), (unit, a, note)
    assert m.registers[0x2000].access == "RW" and m.registers[0x2100].access == "R"
    # decoded with the skeleton's names
    assert {p["name"] for r in recs for p in r["points"]} >= {"holding 2100H", "input 0000H", "holding 2001H"}


def test_learn_real_flow_meter_float_setpoint(tmp_path, capsys):
    """sigrok-dumps flowmeter: register 6-7 holds the flow target, 15.0 then 20.0 l/min as float32."""
    out = tmp_path / "flow.toml"
    code, err = _learn(capsys, FLOW, out, "--baud", "9600")
    assert code == 0, err
    r = load_map(out).registers[6]
    assert r.type == "f32" and "round numbers 15, 20 as float32" in r.note and r.access == "RW"
    flow = load_map(out).registers[2]  # the measured flow: 0x41B8 then 0x0194 / 0x0678 = 23.0008 / 23.0032
    assert flow.type == "f32" and "23.0008..23.0032" in flow.note and flow.access == "R"
    assert 3 not in load_map(out).registers


def test_learn_refuses_to_write_over_its_input(tmp_path, capsys):
    cap = tmp_path / "m.toml"  # a capture named .toml is still the input
    meter_capture(cap, polls=3)
    before = cap.read_bytes()
    line = one_error(capsys, "learn", cap, "--out", cap, "--baud", "9600")
    assert line == f"{cap}: is also an input of this command; write to another file"
    assert cap.read_bytes() == before


def test_learn_bad_invocations_one_line(tmp_path, capsys):
    assert one_error(capsys, "learn", SIM, "--out", tmp_path / "x.json") == (
        f"--out {tmp_path / 'x.json'}: the skeleton is a register map, give a .toml file name")
    missing = tmp_path / "nope.mcap"
    assert "nope.mcap" in one_error(capsys, "learn", missing, "--out", tmp_path / "x.toml")
    assert not (tmp_path / "x.toml").exists() and not list(tmp_path.glob("*.part"))
    code, lines = cli(capsys, "learn", SIM)
    assert code == 2 and "--out" in lines[0]


def test_learn_nothing_to_learn(tmp_path, capsys):
    cap = tmp_path / "coils.csv"
    frames = [_frame(bytes.fromhex("0101000000 08".replace(" ", ""))), _frame(bytes.fromhex("01010155"))]
    rows, t = [], 0.0
    for f in frames:
        for b in f:
            rows.append(f"{t:.6f},RX,{b:02x},")
            t += 0.0012
        t += 0.05
    cap.write_text("t_s,channel,byte_hex,flags\n" + "\n".join(rows) + "\n")
    line = one_error(capsys, "learn", cap, "--out", tmp_path / "x.toml", "--baud", "9600")
    assert line == f"{cap}: no register reads or writes (fc 03/04/06/10) to learn from"
    assert not (tmp_path / "x.toml").exists()


# ---- the guesses, one by one ------------------------------------------------------------------------
def _stats(values) -> RegStats:
    s = RegStats()
    for seq, v in enumerate(values):
        s.add(v, seq, False)
    return s


def test_two_u16_measurements_are_not_a_float():
    rng = random.Random(1)
    volts = _stats([2300 + rng.randint(-30, 30) for _ in range(50)])  # 0x08xx: a tiny float, implausible
    amps = _stats([rng.randint(0, 60000) for _ in range(50)])
    assert guess_pair(volts, amps) is None
    # a rising value next to a noisy one is no u32 counter either (the high word moves without a wrap)
    ramp = _stats(list(range(100, 150)))
    assert guess_pair(ramp, amps) is None


@pytest.mark.parametrize("x", [0.001, 1.5, 230.0, 1e6])
def test_float_guess_over_magnitudes(x):
    rng = random.Random(2)
    pairs = [_words_f(x * (1 + rng.uniform(-0.01, 0.01))) for _ in range(20)]
    g = guess_pair(_stats([p[0] for p in pairs]), _stats([p[1] for p in pairs]))
    assert g is not None and g.type == "f32" and g.word_order == "big"
    lo, hi = (float(v) for v in g.evidence.split(") ")[1].split(" in ")[0].split(".."))
    assert math.isclose(lo, x, rel_tol=0.02) and math.isclose(hi, x, rel_tol=0.02)


def test_word_guesses():
    assert guess_word(_stats([5] * 10)).evidence == "constant 5 (0x0005) in 10 values"
    assert guess_word(_stats([0xFFFE, 0xFFF0, 0xFFFF, 0xFFF8])).type == "s16"
    assert guess_word(_stats([3, 0xFFFD, 10, 0xFFF0])).type == "s16"
    assert guess_word(_stats([100, 40000, 200, 60000])).type == "u16"  # wide both ways: not signed
    assert guess_word(_stats([1, 2, 2, 5, 9])).evidence.startswith("rising (a counter?): rose 3x")
    assert guess_word(RegStats()).evidence == "requested, no value seen (no good response)"


def test_learner_memory_is_bounded():
    s = RegStats()
    for k in range(10_000):
        s.add(k % 1000, k, False)
    assert len(s.samples) == 512 and len(s.distinct) <= 65 and (s.lo, s.hi, s.n) == (0, 999, 10_000)
    assert isinstance(Learner().regs, dict)


def test_learn_refuses_a_pd_series_capture(tmp_path, capsys):
    """PD-series frames are no Modbus register traffic: a map learned from them could not be used."""
    out = tmp_path / "pd.toml"
    line = one_error(capsys, "learn", "captures/sim/pd-series.mcap", "--out", out)
    assert "pd-rtu frames: learn writes Modbus register maps" in line
    assert not out.exists() and not list(tmp_path.glob("*.part"))


def test_learn_keeps_holding_and_input_apart_and_aligns_s32_before_a_float(tmp_path, capsys):
    """Found by an outside review: holding 0000H (a setting, 15) and input 0000H (a float) made one row,
    and an s32 before a float32 lent its low word to a float read one register off."""
    def blocks(rng):
        volts = _words_f(230 + rng.uniform(-3, 3))
        s32 = rng.randint(-500, 500) & 0xFFFFFFFF
        hz = _words_f(50 + rng.uniform(-0.25, 0.25))
        inputs = volts + [0, rng.randint(0, 60000)] + [s32 >> 16, s32 & 0xFFFF] + hz
        return [(4, 0, inputs), (3, 0, [15])]

    cap, out = tmp_path / "meter4.csv", tmp_path / "m4.toml"
    _polls_capture(cap, blocks)
    code, err = _learn(capsys, cap, out, "--baud", "9600")
    assert code == 0, err
    m = load_map(out)
    assert (m.registers[0].table, m.registers[0].type) == ("holding", "u16")
    assert "constant 15" in m.registers[0].note
    i = m.inputs  # every row names its table: a holding read of 0004H is no input's
    assert (i[0].table, i[0].type) == ("input", "f32") and i[4].table == "input" and 4 not in m.registers
    assert (i[4].type, i[6].type, i[6].word_order) == ("s32", "f32", "big")
    assert 5 not in i and 7 not in i
    recs = _replay(capsys, cap, out, ["7=m4"], "--baud", "9600")
    names = {p["name"] for r in recs for p in r["points"]}
    assert {"holding 0000H", "input 0000H", "input 0004H", "input 0006H"} <= names
