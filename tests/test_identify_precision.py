"""Auto-identify, precision first (issue 10 section 2): a name only on evidence one model gives.

Non-drive devices stay generic: an Eastron SDM230 energy meter polled as meters are
(04H reads of 0000H-0049H, float32 values), the sigrok captures (I/O module,
flowmeter, wizmodbus) and the minimalmodbus vectors (Omega CN7500, Delta DTB4824).
Each built-in model's simulated traffic is named within a minute, with its evidence
and a confidence.  A device map wins; a guess the traffic later rules out is withdrawn.
"""

from __future__ import annotations

import struct

import pytest
from refdata import SIGROK, SIGROK_NAMES, sigrok_line, vector_rows

from decoders.identify import SETTLED
from decoders.registry import default_registry
from helpers import bursts, fr
from sniffer.events import CaptureInfo
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.simulator import get_scenario, simulate, wire_chunks
from sniffer.formats.bytecsv.reader import open_byte_csv

METER_LINE = LineSettings(9600, "N", 1)  # the SDM230's factory setting
L = LineSettings(19200, "E", 1)
GUESS, WITHDRAWN, MISMATCH = "model.guess", "model.guess.withdrawn", "model.mismatch"


def run(events, line: LineSettings, devices=None, default="generic", info=None, **kw):
    """(frames, registry) of events through the real pipeline, identification on."""
    registry = default_registry(devices, default=default)
    p = Pipeline(info or CaptureInfo(baud=line.baud, parity=line.parity, stopbits=line.stopbits), line, registry, **kw)
    out = []
    for ev in events:
        out += p.feed(ev)
    return out + p.finish(), registry


def notes(frames, code: str):
    return [(f, a.detail) for f in frames for a in f.annotations if a.code == code]


# ------------------------------------------------------------ an energy meter

# Eastron SDM230 input registers (float32, high word first): what a meter reader polls
SDM230 = {0x0000: 230.4, 0x0006: 4.21, 0x000C: 931.0, 0x0012: 970.0, 0x0018: -272.0, 0x001E: 0.96,
          0x0024: 16.3, 0x0046: 50.01, 0x0048: 1873.52}


def meter_words(t: int) -> dict[int, int]:
    """Register words of 0000H-0049H at poll t: zero where the meter has nothing, values drifting."""
    words = dict.fromkeys(range(0x004A), 0)
    for addr, v in SDM230.items():
        drift = v * (1 + 0.002 * ((t * 7 + addr) % 5 - 2)) if addr != 0x0048 else v + 0.01 * t
        hi, lo = struct.unpack(">HH", struct.pack(">f", drift))
        words[addr], words[addr + 1] = hi, lo
    return words


def read(unit: int, fc: int, a: int, q: int, words: dict[int, int]) -> list[str]:
    data = b"".join(words[a + k].to_bytes(2, "big") for k in range(q))
    return [fr(f"{unit:02x}{fc:02x}{a:04x}{q:04x}"), fr(f"{unit:02x}{fc:02x}{2 * q:02x}{data.hex()}")]


def polls(unit: int, fc: int, blocks, cycles: int, line: LineSettings, period_s: float = 1.0,
          words=meter_words) -> list:
    """A reader polling `blocks` [(address, count)] once a `period_s` for `cycles` cycles."""
    out = []
    for t in range(cycles):
        frames = [h for a, q in blocks for h in read(unit, fc, a, q, words(t))]
        out += bursts(frames, line, gap_chars=4.0, t0=int(t * period_s * 1e9))
    return out


METER_POLLS = {
    "one value per read (04H)": (0x04, [(a, 2) for a in SDM230]),
    "blocks (04H)": (0x04, [(0x0000, 0x26), (0x0046, 4)]),
    "whole 0000H-0049H (04H)": (0x04, [(0x0000, 0x4A)]),
    "blocks as holding (03H)": (0x03, [(0x0000, 0x26), (0x0046, 4)]),
    "one value per read as holding (03H)": (0x03, [(a, 2) for a in SDM230]),
}


@pytest.mark.parametrize("how", METER_POLLS)
def test_energy_meter_stays_generic(how):
    fc, blocks = METER_POLLS[how]
    frames, reg = run(polls(1, fc, blocks, 60, METER_LINE), METER_LINE)
    # (a response whose first 8 bytes happen to be a CRC-valid request is not split: test_framing_edges)
    assert sum(f.crc_ok is True for f in frames) == 2 * 60 * len(blocks)
    assert notes(frames, GUESS) == [] and all(f.model == "generic" for f in frames if not f.is_noise)
    assert not any(p.get("name", "").startswith("Parameter") for f in frames for p in f.points)
    assert reg.guesses == {}


def test_energy_meter_after_four_requests_is_not_spl():
    """The issue's case: the old identifier named the meter spl after four requests."""
    frames, _ = run(polls(1, 0x04, METER_POLLS["one value per read (04H)"][1][:4], 1, METER_LINE), METER_LINE)
    assert len(frames) == 8 and all(f.model == "generic" for f in frames)


def test_meter_answering_a_drives_status_block_is_ruled_out_by_its_values():
    """SPL's supervision block 0120H-012FH exists only in SPL's map, but float32 words are not
    SPL values: 0120H sets status bits the manual calls unused, 0121H is no error code."""
    def words(t):
        w = meter_words(t)
        return {0x0120 + k: w[k] for k in range(16)} | {0x0101: 0, 0x0102: 0}

    frames, reg = run(polls(3, 0x03, [(0x0120, 16), (0x0101, 2)], 30, L, words=words), L)
    assert notes(frames, GUESS) == [] and all(f.model == "generic" for f in frames if not f.is_noise)
    items = reg.identifier.units[3].items["spl"]
    assert {key[1] for key in items if key[0] == "misfit"} == {0x0120, 0x0121}


# ------------------------------------------------------------ reference captures (non-drive devices)


@pytest.mark.parametrize("name", SIGROK_NAMES)
def test_sigrok_captures_stay_generic(name):
    info, events = open_byte_csv(str(SIGROK / f"{name}.bytes.csv"))
    frames, reg = run(events, sigrok_line(name), info=info)
    assert len(frames) > 10
    assert notes(frames, GUESS) == [] and {f.model for f in frames} == {"generic"}
    assert reg.guesses == {}


def test_brainchild_io_module_is_ruled_out_by_its_function_codes():
    info, events = open_byte_csv(str(SIGROK / "brainchild-io-16do.bytes.csv"))
    _, reg = run(events, sigrok_line("brainchild-io-16do"), info=info)
    out = reg.identifier.units[1].ruled_out
    assert set(out) == {"a510", "spl", "tds-v8"}
    assert all("does not implement" in why for why in out.values())


VECTORS = vector_rows()


@pytest.mark.parametrize("row", VECTORS, ids=lambda r: f"{r['set']}-{r['source_line']}")
def test_minimalmodbus_vector_stays_generic(row):
    hexes = [row["request_hex"]] + ([row["response_hex"]] if row["response_hex"] else [])
    frames, _ = run(bursts(hexes, L, gap_chars=4.0), L)
    assert notes(frames, GUESS) == [] and all(f.model in ("generic", None) for f in frames)


def test_minimalmodbus_vectors_on_one_bus_stay_generic():
    """All 118 pairs on one line: the instruments' units collect every answer they gave."""
    hexes = [h for r in VECTORS for h in (r["request_hex"], r["response_hex"]) if h]
    frames, reg = run(bursts(hexes, L, gap_chars=40.0), L)
    assert len(frames) >= 230
    assert notes(frames, GUESS) == [] and reg.guesses == {}
    assert {7, 10} <= set(reg.identifier.units)  # the Delta DTB4824 and the Omega CN7500 were heard


# ------------------------------------------------------------ the built-in models, simulated

MODEL_SCENARIOS = ["tds-v8", "a510", "a510-ascii", "spl", "spl-ascii"]


def simulated(name: str, seconds: float = 60.0, devices=None, default="generic"):
    sc = get_scenario(name)
    sent = list(simulate(sc, sc.line, seconds, 1))
    frames, reg = run(wire_chunks(sent), sc.line, devices=devices or {}, default=default, protocol=sc.protocol)
    assert [f.raw for f in frames] == [s.raw for s in sent]
    return sc, frames, reg


@pytest.mark.parametrize("name", MODEL_SCENARIOS)
def test_each_model_is_named_within_a_minute(name):
    sc, frames, reg = simulated(name)
    t0 = frames[0].t_ns
    guesses = notes(frames, GUESS)
    assert {f.unit for f, _ in guesses} == set(sc.devices)
    for f, detail in guesses:
        truth = sc.devices[f.unit]
        assert f.model == truth and f"looks like {truth}" in detail and "confidence" in detail
        assert f.t_ns - t0 < 60e9
        assert reg.guesses[f.unit][0] == truth and 0.5 <= reg.guesses[f.unit][1] < 1
    assert notes(frames, WITHDRAWN) == []
    for unit, truth in sc.devices.items():  # every frame after the unit's guess is decoded as its model
        named = next(f.index for f, _ in guesses if f.unit == unit)
        assert {f.model for f in frames if f.unit == unit and f.index >= named} == {truth}
        assert truth not in reg.identifier.units[unit].ruled_out
        assert not [k for k in reg.identifier.units[unit].items[truth] if k[0] == "misfit"]


def test_evidence_names_what_only_the_model_gives():
    _, frames, _ = simulated("spl", 20)
    detail = notes(frames, GUESS)[0][1]
    assert "only spl defines" in detail and "0120H-012FH" in detail
    assert "not a510:" in detail and "not tds-v8:" in detail
    _, frames, _ = simulated("a510", 20)
    assert "2520H-252FH" in notes(frames, GUESS)[0][1]


def test_tds_unit_without_vendor_exceptions_is_named_by_being_polled_like_its_twin():
    """Unit 2 draws 21H (busy after an EEPROM save); unit 1 only answers what both are polled for."""
    _, frames, reg = simulated("tds-v8", 20)
    by_unit = {f.unit: d for f, d in notes(frames, GUESS)}
    assert "exception 21H only tds-v8 defines" in by_unit[2]
    assert "polled like unit 2 (tds-v8)" in by_unit[1]
    assert reg.identifier.direct == {2: "tds-v8"}


@pytest.mark.parametrize("name", ["default", "errors"])
def test_generic_simulated_drives_stay_generic(name):
    _, frames, reg = simulated(name, 30)
    assert notes(frames, GUESS) == [] and reg.guesses == {}


def test_pd_series_traffic_is_not_identified():
    """PD frames are not Modbus: the identifier leaves them to the protocol's model."""
    _, frames, reg = simulated("pd-series", 30, default="pd-series")
    assert notes(frames, GUESS) == [] and reg.identifier.units == {}
    assert {f.model for f in frames if not f.is_noise} == {"pd-series"}


def test_verdict_settles_so_the_hot_path_stays_cheap():
    sc, _, reg = simulated("a510", 60)
    for unit in sc.devices:
        assert reg.identifier.settled(unit) and reg.identifier.units[unit].seen == SETTLED
        assert unit in reg._routes  # decoded without the identifier from then on


# ------------------------------------------------------------ the user's map, withdrawal, ambiguity


def test_user_map_wins_and_mismatch_says_what_rules_the_map_out():
    sc, frames, reg = simulated("spl", 20, devices={1: "a510"})
    assert {f.model for f in frames if f.unit == 1} == {"a510"}
    assert {f.model for f in frames if f.unit == 2} == {"generic", "spl"}
    (f, detail), = notes(frames, MISMATCH)
    assert f.unit == 1 and "mapped to a510 but looks like spl" in detail and "which a510" in detail


def test_user_map_of_the_right_model_is_not_contradicted():
    for name in MODEL_SCENARIOS:
        sc, frames, _ = simulated(name, 20, devices=get_scenario(name).devices)
        assert notes(frames, MISMATCH) == [] and notes(frames, GUESS) == []


A510_POLL = read(2, 0x03, 0x2520, 4, {0x2520: 0x0005, 0x2521: 0, 0x2522: 0x0001, 0x2523: 5000}) + [
    fr("020625020fa0"), fr("020625020fa0")]


def test_guess_ruled_out_later_is_withdrawn():
    """An A510-looking unit that then answers 04H (no A510 function) is generic again."""
    later = read(2, 0x04, 0x0000, 2, {0: 1, 1: 2})
    frames, reg = run(bursts(A510_POLL * 2 + later * 2, L), L)
    (g, detail), = notes(frames, GUESS)
    assert "a510" in detail
    (w, why), = notes(frames, WITHDRAWN)
    assert w.index > g.index and "not a510: answered function 04H" in why
    assert frames[-1].model == "generic" and reg.guesses == {}


def test_vendor_exception_alone_is_not_enough():
    """51H-55H are SPL's, but a unit that never answers anything SPL's map holds is not named."""
    exc = [fr("050301300002"), fr("058352")]  # 0130H: nothing there
    frames, _ = run(bursts(exc * 5, L), L)
    assert notes(frames, GUESS) == []
    # with one answer SPL's map holds (its command words), the exception is enough
    frames, _ = run(bursts(exc + read(5, 0x03, 0x0101, 2, {0x0101: 1, 0x0102: 3000}), L), L)
    (f, detail), = notes(frames, GUESS)
    assert "looks like spl" in detail and "exception 52H only spl defines" in detail


def test_bare_parameters_only_one_map_holds_are_not_enough():
    """A temperature controller at 1000H-1009H (A510 parameters 16-00..16-09: the map says only
    that they exist) answering 03H/06H only: 1 point from bare rows in all, never a name."""
    words = dict.fromkeys(range(0x1000, 0x100A), 250)
    traffic = [h for a in range(0x1000, 0x100A) for h in read(7, 0x03, a, 1, words)]
    traffic += [fr("070610010320"), fr("070610010320")]
    frames, reg = run(bursts(traffic * 3, L), L)
    assert notes(frames, GUESS) == []
    assert reg.identifier.score(reg.identifier.units[7].items["a510"]) == 1


def test_evidence_for_two_models_stays_generic():
    """2520H answered (only A510 has it) and exception 52H (only SPL defines it): rules both out."""
    traffic = read(4, 0x03, 0x2520, 4, {0x2520: 5, 0x2521: 0, 0x2522: 0, 0x2523: 0})
    traffic += [fr("040301300002"), fr("048352")]
    frames, reg = run(bursts(traffic * 4, L), L)
    assert notes(frames, GUESS) == []
    assert {"a510", "spl"} <= set(reg.identifier.units[4].ruled_out)


def test_meter_next_to_an_identified_drive_does_not_take_its_name():
    """A TDS-V8 at unit 2 (named by its 21H) and a meter at unit 5 read at the same addresses:
    the meter's float words set the TDS status word's reserved bits 8-10, so it stays generic."""
    tds = dict.fromkeys(range(0x0020, 0x0030), 0) | {0x0000: 0x0101, 0x0001: 15000, 0x0020: 0x0019,
                                                       0x0024: 15000, 0x0025: 14990, 0x0026: 200, 0x0028: 311}
    meter = meter_words(0)
    meter = {0x0000: meter[0], 0x0001: meter[1]} | {0x0020 + k: meter[k] for k in range(16)}
    traffic = []
    for _ in range(6):
        traffic += read(2, 0x03, 0x0020, 16, tds) + read(2, 0x03, 0x0000, 2, tds)
        traffic += read(5, 0x03, 0x0020, 16, meter) + read(5, 0x03, 0x0000, 2, meter)
    traffic += [fr("020301000001"), fr("028321")]
    traffic += read(5, 0x03, 0x0020, 16, meter)
    frames, reg = run(bursts(traffic, L), L)
    assert {f.unit: d.split(":")[0] for f, d in notes(frames, GUESS)} == {2: "unit 2 looks like tds-v8"}
    assert {f.model for f in frames if f.unit == 5} == {"generic"}


# ---- found by an outside review: generic devices with big register spaces ----------------------
@pytest.mark.parametrize("blocks, values", [
    ([(0x0264, 8), (0x0270, 8)], lambda k: (k * 97) % 1001),  # SPL's PLC timer/counter words: 0..1000
    ([(0x0123, 1), (0x0124, 1)], lambda k: 1 + k % 7),         # two single registers in 0100H-01FFH
    ([(0x0420, 4), (0x0430, 4)], lambda k: 1 + k % 8),         # TDS-V8 Sn-33.. settings: small integers
    ([(0x0415, 8)], lambda k: k % 3),
    ([(0x0C01, 4), (0x0D00, 4)], lambda k: 10 * k),            # A510 parameter groups 12/13
], ids=["spl-plc-words", "two-singles", "tds-sn-small-ints", "tds-sn-0415", "a510-params"])
def test_a_device_with_a_big_register_space_stays_generic(blocks, values):
    words = {a + k: values(a + k) for a, q in blocks for k in range(q)}
    traffic = [h for a, q in blocks for h in read(9, 0x03, a, q, words)]
    frames, reg = run(bursts(traffic * 20, L), L)
    assert notes(frames, GUESS) == [] and reg.guesses == {}
    assert {f.model for f in frames if not f.is_noise} == {"generic"}


def test_an_echoed_write_to_a_read_only_register_rules_the_model_out():
    """SPL's 0123H/0125H are monitor values (read-only): a device that echoes writes to them is no SPL."""
    traffic = [fr("090601230065"), fr("090601230065"), fr("090601250003"), fr("090601250003")]
    frames, reg = run(bursts(traffic * 5, L), L)
    assert notes(frames, GUESS) == []
    assert "read-only" in reg.identifier.ruled_out(9, "spl")


def test_a_unit_answering_zeros_is_not_polled_like_a_named_drive():
    """Third outside review: a unit polled like a TDS-V8 named by its 22H, answering zeros (which fit every
    table), took the name with no evidence of its own.  It must show the model's shape first."""
    tds = dict.fromkeys(range(0x0020, 0x0030), 0) | {0x0000: 0x0001, 0x0001: 3000, 0x0020: 0x0802}
    zeros = dict.fromkeys(range(0x0020, 0x0030), 0) | {0x0000: 0, 0x0001: 0x00E6}
    traffic = []
    for _ in range(10):
        traffic += read(1, 0x03, 0x0000, 2, tds) + read(1, 0x03, 0x0020, 16, tds)
        traffic += read(2, 0x03, 0x0000, 2, zeros) + read(2, 0x03, 0x0020, 16, zeros)
    traffic += [fr("010301000001"), fr("018322")]
    traffic += read(2, 0x03, 0x0000, 2, zeros) + read(2, 0x03, 0x0020, 16, zeros)
    frames, reg = run(bursts(traffic, L), L)
    assert {f.unit: d.split(":")[0] for f, d in notes(frames, GUESS)} == {1: "unit 1 looks like tds-v8"}
    assert {f.model for f in frames if f.unit == 2} == {"generic"}
