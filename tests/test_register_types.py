"""Register types (docs/register-map-format.md "Types"): values of several registers, word and byte
order, strings, bit fields; in the map loader, the decoder, the register watch and the exports.

Byte layouts come from outside: the minimalmodbus test vectors (captures/refcaptures/vectors,
Apache-2.0: one 32-bit value in all four byte orders, a 64-bit integer and double, strings) and a
real flowmeter capture (captures/refcaptures/sigrok, public domain: float32 registers, and a float
target written with FC 16).  The A510's 12-00 (2510H high word, 2511H low word) is the manual's.
"""

from __future__ import annotations

import asyncio
import csv
import struct
from pathlib import Path

import tomllib

import pytest
from helpers import bursts, export, fr, run_sniffer
from refdata import VECTORS

from decoders.model_info import ModelInfo
from decoders.registry import default_registry
from decoders.tables import MapError, Register, RegisterMap, lint, load_map
from sniffer.events import CaptureInfo
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.tui.store import FrameStore

ROOT = Path(__file__).resolve().parent.parent
FLOWMETER = ROOT / "captures" / "refcaptures" / "sigrok" / "flowmeter_target_15liter_per_min.bytes.csv"
LINE = LineSettings(19200, "N", 1)
# (word_order, byte_order) of the four layouts the vectors hold at consecutive addresses, read off their bytes
ORDERS = [("big", "little"), ("big", "big"), ("little", "little"), ("little", "big")]


def vectors(section: str) -> list[tuple[str, str]]:
    """(request hex, response hex) of the good minimalmodbus rows of one section."""
    rows = csv.DictReader(VECTORS.open())
    return [(r["request_hex"], r["response_hex"]) for r in rows if r["set"] == "good" and r["section"] == section]


def model_file(tmp_path, rows: str, model_id: str = "t", extra: str = "") -> Path:
    p = tmp_path / f"{model_id}.toml"
    p.write_text(f"registers = [\n{rows}\n]\n[model]\nid = \"{model_id}\"\n{extra}")
    return p


def decode(frames_hex: list[str], devices: dict[int, str], model_files=()) -> list:
    """Frames through the real pipeline (framer, pairer, registry with the given maps), in order."""
    registry = default_registry(devices, [str(p) for p in model_files])
    p = Pipeline(CaptureInfo(baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits), LINE, registry)
    out = []
    for ev in bursts(frames_hex, LINE, gap_chars=8):
        out += p.feed(ev)
    out += p.finish()
    return sorted(out, key=lambda f: f.index)


def codes(f) -> list[str]:
    return [a.code for a in f.annotations]


# ---- the same value in the four byte orders (minimalmodbus READ LONG / READ FLOAT) -----------------------
# registers 00DFH-00E2H hold one 32-bit integer and 00F1H-00F4H one float, each in another order:
# AE41 5652 (big words, bytes swapped), 41AE 5256 (big/big), 5652 AE41 (little/little), 5256 41AE (little/big)
# (minimalmodbus's BYTEORDER_LITTLE_SWAP, BIG, LITTLE, BIG_SWAP)

def _layouts(section: str, first: int) -> list[tuple[str, str]]:
    got = {int(q[4:8], 16): (q, r) for q, r in vectors(section) if r[4:6] == "04"}
    return [got[first + k] for k in range(4)]


@pytest.mark.parametrize("type_, section, first, fmt", [
    ("s32", "READ LONG", 0x00DF, ">i"), ("u32", "READ LONG", 0x00DF, ">I"), ("f32", "READ FLOAT", 0x00F1, ">f"),
])
def test_one_value_in_four_byte_orders(tmp_path, type_, section, first, fmt):
    layouts = _layouts(section, first)
    big = bytes.fromhex(layouts[1][1][6:14])  # the big/big layout is the value's bytes as they are
    (want,) = struct.unpack(fmt, big)
    values, wrong = [], []
    for k, ((wo, bo), (req, rsp)) in enumerate(zip(ORDERS, layouts)):
        mid = f"o{k}"
        path = model_file(tmp_path, f'{{ addr = {first + k}, name = "V", type = "{type_}", word_order = "{wo}", '
                                    f'byte_order = "{bo}", section = "t" }},', mid)
        got = decode([req, rsp], {1: mid}, [path])
        (pt,) = got[1].points
        assert pt["address"] == first + k and pt["span"] == [3, 7] and len(pt["words"]) == 2
        assert got[1].annotations == []
        values.append(pt["value"])
        other = model_file(tmp_path, f'{{ addr = {first + k}, name = "V", type = "{type_}", section = "t" }},', "plain")
        wrong.append(decode([req, rsp], {1: "plain"}, [other])[1].points[0]["value"])
    if type_ == "f32":
        assert values == [pytest.approx(want, rel=1e-7)] * 4 and values[0] == pytest.approx(21.790203, rel=1e-7)
    else:
        assert values == [want] * 4
    assert wrong[1] == values[0] and all(wrong[k] != values[0] for k in (0, 2, 3))  # the order matters


def test_float32_12_5_both_word_orders(tmp_path):
    path = model_file(tmp_path, '{ addr = 0, name = "Hi first", type = "f32", unit = "Hz", section = "t" },\n'
                                '{ addr = 2, name = "Lo first", type = "float32", word_order = "little", '
                                'section = "t" },')
    f = decode([fr("010300000004"), fr("0103084148000000004148")], {1: "t"}, [path])[1]
    assert [(p["name"], p["value"], p["raw"], p["words"], p["span"]) for p in f.points] == [
        ("Hi first", 12.5, 0x41480000, [0x4148, 0], [3, 7]), ("Lo first", 12.5, 0x41480000, [0, 0x4148], [7, 11])]
    assert f.summary == "Hi first=12.5 Hz Lo first=12.5"


def test_64_bit_and_double_and_shortest_float(tmp_path):
    (long64,) = [v for v in vectors("READ LONG") if v[0][10:12] == "04"]  # 006CH, 4 registers: FFFF FFFF FFFF FFFE
    (dbl,) = [v for v in vectors("READ FLOAT") if v[0][10:12] == "04"]  # 0067H, 4 registers: C000 0000 0000 0000
    f32_write = next(q for q, _ in vectors("WRITE FLOAT") if q[4:8] == "0067" and q[12:14] == "04")  # 3F8C CCCD
    f64_write = next(q for q, _ in vectors("WRITE FLOAT") if q[12:14] == "08")  # 3FF1 9999 9999 999A = 1.1
    rows = ('{ addr = 0x6C, name = "S", type = "s64", section = "t" },\n'
            '{ addr = 0x70, name = "F", type = "f64", section = "t" },')
    got = decode(list(long64), {1: "t"}, [model_file(tmp_path, rows)])
    assert got[1].points[0]["value"] == -2 and got[1].points[0]["raw"] == (1 << 64) - 2
    path = model_file(tmp_path, '{ addr = 0x6C, name = "U", type = "u64", section = "t" },', "u")
    assert decode(list(long64), {1: "u"}, [path])[1].points[0]["value"] == (1 << 64) - 2
    path = model_file(tmp_path, '{ addr = 0x67, name = "D", type = "f64", section = "t" },', "d")
    got = decode([*dbl, f64_write], {1: "d"}, [path])
    assert got[1].points[0]["value"] == -2.0 and got[2].points[0]["value"] == 1.1
    path = model_file(tmp_path, '{ addr = 0x67, name = "F", type = "f32", section = "t" },', "f")
    pt = decode([f32_write], {1: "f"}, [path])[0].points[0]
    assert pt["raw"] == 0x3F8CCCCD and pt["value"] == 1.1  # the float32 nearest 1.1, shown as 1.1
    inp = next(v for v in vectors("READ FLOAT") if v[0][2:4] == "04")  # input register 0067H: 7238 4725
    assert decode(list(inp), {1: "f"}, [path])[1].points[0]["value"] == 3.65e30


def test_strings(tmp_path):
    path = model_file(tmp_path, '{ addr = 0x68, name = "Tag", type = "str", words = 4, section = "t" },')
    reads = [v for v in vectors("READ STRING")]
    got = decode([x for v in reads for x in v], {1: "t"}, [path])
    one, four = got[1], got[3]
    assert one.points[0]["name"] == "Tag [word 1/4]" and "model.register.split" in codes(one)
    assert codes(got[0]) == ["model.register.split"]  # the request reads the first register of four
    assert "cuts Tag (str at 0x0068..0x006B)" in got[0].annotations[0].detail
    assert four.points[0]["value"] == "ABCDEFGH" and four.points[0]["raw"] == b"ABCDEFGH".hex()
    assert four.summary == "Tag=ABCDEFGH"
    writes = [q for q, _ in vectors("WRITE STRING") if q[12:14] == "08"]
    assert [decode([q], {1: "t"}, [path])[0].points[0]["value"] for q in writes] == ["A", "ABCDEFGH"]
    swapped = model_file(tmp_path, '{ addr = 0x68, name = "Tag", type = "str", words = 4, byte_order = "little", '
                                   'section = "t" },', "sw")
    assert decode(list(reads[1]), {1: "sw"}, [swapped])[1].points[0]["value"] == "BADCFEHG"
    # bytes outside ASCII are kept visible, not dropped
    f = decode([fr("010300680004"), fr("01030841ff430000000000")], {1: "t"}, [path])[1]
    assert f.points[0]["value"] == "A\\xffC"


def test_bit_fields_of_32_bit_registers(tmp_path):
    path = model_file(tmp_path, '{ addr = 0, name = "Flags", type = "u32", bits = "f", section = "t" },\n'
                                '{ addr = 2, name = "Small", type = "s16", bits = "g", section = "t" },',
                      extra='[bits.f]\n"0" = "run"\n"16-17" = { name = "mode", values = { "2" = "auto" } }\n'
                            '"31" = "fault"\n[bits.g]\n"15" = "sign"\n"0-3" = { name = "low" }\n')
    f = decode([fr("010300000003"), fr("01030680020001ffff")], {1: "t"}, [path])[1]
    assert [p["text"] for p in f.points] == ["run, mode=auto, fault", "low=15, sign"]
    assert f.points[0]["raw"] == 0x80020001 and f.points[1]["value"] == -1


# ---- A510 12-00: 2510H high word, 2511H low word (manual l.276-277, l.1024-1027) -------------------------

def test_a510_12_00_is_one_point_and_halves_are_flagged():
    frames = [fr("010325100002"), fr("0103040001e240"),  # read both: one value 0x0001E240
              fr("0110251000020400020003"), fr("011025100002"),  # write both
              fr("01062511e240"), fr("01062511e240"),  # write the low word alone
              fr("010325110001"), fr("0103020007")]  # read the low word alone
    got = decode(frames, {1: "a510"})
    rsp = got[1]
    assert [(p["id"], p["address"], p["value"], p["span"]) for p in rsp.points] == [("12-00", 0x2510, 123456, [3, 7])]
    assert rsp.annotations == [] and rsp.summary == "Parameter 12-00=123456"
    assert got[2].points[0]["value"] == 0x00020003 and got[2].annotations == []
    for f in (got[4], got[5], got[7]):
        (pt,) = f.points
        assert pt["address"] == 0x2511 and pt["part"] == [1, 2] and pt["value"] == pt["raw"]
        assert codes(f) == ["model.register.split"] and "model.register.unknown" not in codes(f)
    assert "word 2/2" in got[4].summary
    assert codes(got[6]) == ["model.register.split"]  # the read request that cuts the value
    assert "cuts 12-00 (u32 at 0x2510..0x2511)" in got[6].annotations[0].detail


def test_a510_cli_decode():
    r = run_sniffer("decode", "--device", "1=a510", fr("010325100002"), fr("0103040001e240"), fr("01062510e240"))
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "Parameter 12-00=123456" in lines[1] and "holding[9489]" not in r.stdout
    assert "model.register.split" in lines[2] and "model.register.unknown" not in r.stdout


# ---- a --model-file using the types, on a real capture ---------------------------------------------------

FLOW_MAP = """registers = [
  { addr = 0x0000, name = "Float 0000H", type = "f32", access = "R", section = "capture" },
  { addr = 0x0002, name = "Float 0002H", type = "f32", access = "R", section = "capture" },
  { addr = 0x0004, name = "Float 0004H", type = "f32", access = "R", section = "capture" },
  { addr = 0x0006, name = "Target flow", type = "f32", unit = "l/min", section = "15 l/min capture: written" },
  { addr = 0x0008, name = "Float 0008H", type = "f32", access = "R", section = "capture" },
]
[model]
id = "flowmeter"
"""


def test_model_file_with_floats_on_a_real_capture(tmp_path):
    m = tmp_path / "flowmeter.toml"
    m.write_text(FLOW_MAP)
    assert lint(load_map(m)) == []
    r = run_sniffer("replay", str(FLOWMETER), "--baud", "9600", "--stopbits", "2", "--model-file", str(m),
                    "--device", "247=flowmeter")
    assert r.returncode == 0, r.stderr
    writes = [ln for ln in r.stdout.splitlines() if "fc10" in ln and "REQ" in ln]
    assert writes and all("write Target flow=15.0 l/min" in ln for ln in writes)
    reads = [ln for ln in r.stdout.splitlines() if "Float 0002H=" in ln]
    assert reads and "Float 0000H=0.0 Float 0002H=23.00077" in reads[0]
    assert "model.register.split" not in r.stdout


# ---- the map format --------------------------------------------------------------------------------------

def test_register_rows_carry_type_words_and_orders():
    r = Register(0x10, "", "x", type="float32", word_order="little")
    assert (r.type, r.words, r.width, r.word_order, r.byte_order) == ("f32", 2, 2, "little", "big")
    assert Register(0, "", "s", type="str", words=5).words == 5
    assert Register(0, "", "q", type="u64").words == 4
    for bad in (dict(type="str"), dict(type="u32", words=3), dict(type="x"), dict(byte_order="middle")):
        with pytest.raises(MapError):
            Register(0, "", "bad", **bad)


def test_model_defaults_for_order_and_lint(tmp_path):
    path = model_file(tmp_path, '{ addr = 0, name = "A", type = "u32", section = "t" },\n'
                                '{ addr = 2, name = "B", type = "u32", word_order = "big", section = "t" },\n'
                                '{ addr = 4, name = "T", type = "str", words = 2, section = "t" },',
                      extra='word_order = "little"\nbyte_order = "little"\n')
    m = load_map(path)
    assert [(r.word_order, r.byte_order) for r in m.registers.values()] == [
        ("little", "little"), ("big", "little"), ("big", "little")]
    assert m.covering(1) == (m.registers[0], 1) and m.covering(5) == (m.registers[4], 1)
    bad = model_file(tmp_path, '{ addr = 2, name = "F", type = "f32", enum = "e", section = "t" },\n'
                               '{ addr = 4, name = "W", type = "u16", bits = "b", section = "t" },\n'
                               '{ addr = 5, name = "S", type = "str", words = 1, scale = 0.1, section = "t" },',
                     "bad", extra='[enums.e]\n"1" = "one"\n[bits.b]\n"20" = "far"\n')
    with pytest.raises(MapError, match=r"bad.toml: 0x0002: a f32 takes no enum \(and 2 more\)"):
        load_map(bad)  # the loader lints every map, a user's too
    doc = tomllib.loads(Path(bad).read_text())
    doc["registers"] = [dict(r) for r in doc["registers"]]
    rows = {r["addr"]: Register(**{"id": "", **r}) for r in doc["registers"]}
    m = RegisterMap(ModelInfo.from_table(doc["model"], MapError), rows, {}, {}, {})
    m.enums = {"e": {1: {"text": "one"}}}
    m.bits = {"b": [{"lo": 20, "hi": 20, "name": "far"}]}
    assert lint(m) == ["0x0002: a f32 takes no enum",
                       "0x0004: bits 'b' field 'far' past bit 15", "0x0005: a str takes no scale"]
    overlap = model_file(tmp_path, '{ addr = 0, name = "A", type = "u32", section = "t" },\n'
                                   '{ addr = 1, name = "B", type = "u16", section = "t" },', "overlap")
    with pytest.raises(MapError, match=r"register 0x0001 is inside 0x0000 \(A, a u32 of 2 registers\)"):
        load_map(overlap)  # a user's map too, not only the built-in maps' lint


# ---- the register watch ----------------------------------------------------------------------------------

A510_FRAMES = [fr("010325110001"), fr("0103020007"),  # the low word alone first: a raw row at 2511H
               fr("010325100002"), fr("0103040001e240"),  # then both: one row 12-00 at 2510H
               fr("0110251000020400020003"), fr("011025100002")]  # a write both ways, confirmed


def test_watch_shows_the_combined_value():
    frames = decode(A510_FRAMES, {1: "a510"})
    s = FrameStore(frames[0].t_ns)
    s.add(frames[:2])
    assert [(r.address, r.words, r.raw) for r in s.register_rows(1)] == [(0x2511, 1, 7)]
    s.add(frames[2:4])
    (row,) = s.register_rows(1)
    assert (row.address, row.words, row.value, row.raw, row.id) == (0x2510, 2, 123456, 123456, "12-00")
    s.add(frames[4:])
    (row,) = s.register_rows(1)
    assert row.value == 0x00020003 and row.changes == 1 and list(row.history) == [123456, 0x00020003]
    # a viewer attached over a socket rebuilds the frames from their JSON records: the same watch
    from sniffer.formats.records import frame_json, loads
    from sniffer.tui.store import frame_from_record

    t0 = frames[0].t_ns
    attached = FrameStore(t0)
    attached.add([frame_from_record(loads(frame_json(f, t0)), t0) for f in frames])
    assert [(r.address, r.words, r.value, r.raw) for r in attached.register_rows(1)] == [
        (0x2510, 2, 0x00020003, 0x00020003)]


def test_a_half_read_or_write_after_the_whole_never_shows_as_the_value():
    """Found by an outside review: a 1-register read of 12-00's halves overwrote the joined row (and its
    plot) with the half's raw number.  Now the row keeps its value, says it is stale, and the next
    whole read sets it again."""
    halves = [fr("010325100001"), fr("0103020001"),  # the high word alone
              fr("010625110007"), fr("010625110007"),  # the low word written alone
              fr("010325100002"), fr("01030400010007")]  # whole again: 0x00010007
    frames = decode(A510_FRAMES[2:4] + halves, {1: "a510"})
    s = FrameStore(frames[0].t_ns)
    s.add(frames[:2])
    s.add(frames[2:6])
    (row,) = s.register_rows(1)
    assert (row.address, row.words, row.value) == (0x2510, 2, 123456) and list(row.history) == [123456]
    assert row.text == "word 2/2 now 0007H: value as of the last whole read"
    s.add(frames[6:])
    (row,) = s.register_rows(1)
    assert (row.value, row.text, list(row.history)) == (0x00010007, "", [123456, 0x00010007])


def test_watch_under_pilot_shows_one_row_per_value():
    from sniffer.tui.app import SnifferApp
    from sniffer.tui.sink import TuiSink

    frames = decode(A510_FRAMES[:4], {1: "a510"})

    async def go():
        sink = TuiSink()
        sink.start(CaptureInfo(baud=LINE.baud, t0_ns=frames[0].t_ns))
        sink.frames(frames)
        sink.close()
        app = SnifferApp(sink, None, clock=lambda: 0.0)
        async with app.run_test(size=(140, 45)) as pilot:
            app.poll()
            await pilot.pause()
            await pilot.press("3")
            await pilot.pause()
            regs = app.query_one("#regs")
            assert regs.row_count == 1
            cells = [str(c) for c in regs.get_row("1:holding:9488")]
            assert cells[:5] == ["1", "holding", "2510H..2511H", "Parameter 12-00", "123456"]
    asyncio.run(go())


# ---- exports ---------------------------------------------------------------------------------------------

def _byte_csv(path: Path, frames_hex: list[str]) -> None:
    lines = ["t_s,channel,byte_hex,flags"]
    for ev in bursts(frames_hex, LINE, gap_chars=20):
        lines += [f"{t / 1e9:.9f},,{b:02x}," for t, b in zip(ev.byte_t_ns, ev.data)]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_export_round_trip(tmp_path, fmt):
    cap = tmp_path / "types.csv"
    _byte_csv(cap, [fr("010325100002"), fr("0103040001e240"),
                    fr("020300000010"), fr("02032041480000ffffffffffffffff41424344454647480000000000000000fffffffe")])
    m = model_file(tmp_path, '{ addr = 0, name = "F", type = "f32", section = "t" },\n'
                             '{ addr = 2, name = "U", type = "u64", section = "t" },\n'
                             '{ addr = 6, name = "S", type = "str", words = 4, section = "t" },\n'
                             '{ addr = 10, name = "N", type = "s64", word_order = "little", section = "t" },\n'
                             '{ addr = 14, name = "I", type = "s32", section = "t" },')
    out = tmp_path / f"out.{fmt}"
    assert export(cap, fmt, out, "--baud", str(LINE.baud), "--model-file", str(m),
                  "--device", "1=a510", "--device", "2=t") == 0
    pts_path = tmp_path / f"out.points.{fmt}"
    if fmt == "csv":
        rows = list(csv.DictReader(pts_path.open()))
        conv = {"raw": lambda v: int(v) if v else None, "value": lambda v: float(v) if v else None}
        rows = [{k: conv.get(k, lambda v: v)(v) for k, v in r.items()} for r in rows]
    else:
        import pyarrow.parquet as pq

        rows = pq.read_table(pts_path).to_pylist()
    got = {r["name"]: (r["address"] if fmt == "parquet" else int(r["address"]), r["raw"], r["value"], r["value_text"])
           for r in rows}
    assert got == {
        "Parameter 12-00": (0x2510, 123456, 123456.0, "123456"),
        "F": (0, 0x41480000, 12.5, "12.5"),
        "U": (2, None, float((1 << 64) - 1), str((1 << 64) - 1)),  # above int64: raw null, the text exact
        "S": (6, None, None, "ABCDEFGH"),
        "N": (10, 0, 0.0, "0"),
        "I": (14, 0xFFFFFFFE, -2.0, "-2"),
    }
