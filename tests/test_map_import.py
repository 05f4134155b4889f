"""Register maps from the formats plants already have: plain CSV and Home Assistant modbus YAML.

Each format round-trips: file -> map -> frames decoded through the CLI with the file's names and
scaled values, and map -> the TOML the project writes -> the same map.  Bad files give one error
line naming the file and its line, exit 2.
"""

from __future__ import annotations

import glob
import json
import struct

import pytest

from decoders.mapformats import load_model_file, to_toml
from decoders.tables import MapError, load_map
from sniffer.cli import main
from tests.helpers import fr
from tests.test_bad_input import cli, one_error

# a meter with float32s (both word orders), a scaled s16, a u32, a string
CSV = """\
# model: meter-a
# name: ACME meter A
address,name,type,scale,unit,access,description,word_order,words
0x0000,Voltage,float32,,V,R,Line to neutral,ABCD,
0002H,Current,float32,,A,R,,CDAB,
16,Temperature,s16,0.1,°C,R,signed tenths,,
17,Setpoint,u16,0.01,Hz,RW,,,
0x0012,Energy,u32,,Wh,R,,,
0x0020,Serial number,str,,,R,,,4
"""


def _decode(capsys, model_file, unit, model, *frames, extra=()):
    """Frames through `sniffer decode --format jsonl` with the map: the records."""
    code = main(["decode", *frames, "--model-file", str(model_file), "--device", f"{unit}={model}",
                 "--format", "jsonl", *extra])
    out, err = capsys.readouterr()
    assert code == 0, err
    return [json.loads(line) for line in out.splitlines()]


def _points(records) -> dict[str, tuple]:
    return {p["name"]: (p["address"], p["value"], p["unit"]) for r in records for p in r["points"]}


def _same(a, b) -> None:
    assert a.registers == b.registers and a.inputs == b.inputs
    assert (a.model, a.enums, a.bits, a.exceptions) == (b.model, b.enums, b.bits, b.exceptions)


def _round_trip(m, tmp_path):
    out = tmp_path / f"{m.model_id}.toml"
    out.write_text(to_toml(m), encoding="utf-8")
    back = load_map(out)
    _same(m, back)
    return out


# ---- CSV -------------------------------------------------------------------------------------
def test_csv_map_fields(tmp_path):
    p = tmp_path / "meter.csv"
    p.write_text(CSV, encoding="utf-8")
    [m] = load_model_file(str(p))
    assert m.model_id == "meter-a" and m.model.name == "ACME meter A"
    r = m.registers
    assert sorted(r) == [0, 2, 16, 17, 18, 32]
    assert (r[0].type, r[0].word_order, r[0].unit, r[0].access, r[0].note) == ("f32", "big", "V", "R",
                                                                               "Line to neutral")
    assert (r[2].type, r[2].word_order, r[2].byte_order) == ("f32", "little", "big")
    assert (r[16].type, r[16].scale, r[16].unit) == ("s16", 0.1, "°C")
    assert (r[17].access, r[17].scale) == ("RW", 0.01)
    assert (r[18].type, r[18].width) == ("u32", 2)
    assert (r[32].type, r[32].words, r[32].width) == ("str", 4, 4)
    assert r[16].section == "meter.csv line 6"


def test_csv_decodes_and_round_trips(tmp_path, capsys):
    p = tmp_path / "meter.csv"
    p.write_text(CSV, encoding="utf-8")
    # read 16..17: Temperature = -12.5 °C (0xFF83), Setpoint = 49.98 Hz
    recs = _decode(capsys, p, 4, "meter-a", fr("040300100002"), fr("040304FF831386"))
    pts = _points(recs)
    assert pts["Temperature"] == (16, -12.5, "°C") and pts["Setpoint"] == (17, 49.98, "Hz")
    # a write of the RW register carries its name too; the read-only one is flagged
    assert _points(_decode(capsys, p, 4, "meter-a", fr("040600110FA0")))["Setpoint"] == (17, 40.0, "Hz")
    [rec] = _decode(capsys, p, 4, "meter-a", fr("040600100001"))
    assert "model.write.read_only" in [a["code"] for a in rec["annotations"]]
    [m] = load_model_file(str(p))
    toml = _round_trip(m, tmp_path)
    # the TOML it wrote decodes the same frames the same way
    assert _points(_decode(capsys, toml, 4, "meter-a", fr("040300100002"), fr("040304FF831386"))) == pts


def test_csv_float32_decodes_as_float(tmp_path, capsys):
    p = tmp_path / "meter.csv"
    p.write_text(CSV, encoding="utf-8")
    v, c = struct.pack(">f", 230.5), struct.pack(">f", 4.25)
    body = (v + c[2:] + c[:2]).hex()  # Current is CDAB: low word first
    pts = _points(_decode(capsys, p, 4, "meter-a", fr("040300000004"), fr("040308" + body)))
    assert pts["Voltage"][1] == 230.5 and pts["Current"][1] == 4.25


def test_csv_semicolons_decimal_comma_and_stem_id(tmp_path):
    p = tmp_path / "pump 3.csv"
    p.write_text("Address;Name;Type;Scale;Unit;Access;Description\n"
                 "2524H;Output frequency;uint16;0,01;Hz;RO;\n0x2525;Current;int16;0,1;A;r/w;x\n", encoding="utf-8")
    [m] = load_model_file(str(p))
    assert m.model_id == "pump 3"
    assert m.registers[0x2524].scale == 0.01 and m.registers[0x2524].access == "R"
    assert m.registers[0x2525].type == "s16" and m.registers[0x2525].access == "RW"


def test_csv_one_based_from_the_file_and_the_flag(tmp_path, capsys):
    rows = "address,name,scale,unit\n1,First,0.1,V\n10,Tenth,,\n"
    in_file = tmp_path / "onebased.csv"
    in_file.write_text("# base: 1\n" + rows)
    flag = tmp_path / "plain.csv"
    flag.write_text(rows)
    assert sorted(load_model_file(str(in_file))[0].registers) == [0, 9]
    assert sorted(load_model_file(str(flag))[0].registers) == [1, 10]
    assert sorted(load_model_file(str(flag), "1")[0].registers) == [0, 9]
    # through the CLI: --map-base 1 puts "1" at register 0
    pts = _points(_decode(capsys, flag, 1, "plain", fr("010300000001"), fr("0103020929"),
                          extra=("--map-base", "1")))
    assert pts["First"] == (0, 234.5, "V")


def test_csv_modicon_addresses(tmp_path):
    p = tmp_path / "modicon.csv"
    p.write_text("# base: modicon\naddress,name\n40001,Holding one\n30003,Input three\n400101,Six digits\n")
    [m] = load_model_file(str(p))
    assert {a: r.name for a, r in m.registers.items()} == {0: "Holding one", 100: "Six digits"}
    assert {a: (r.name, r.table) for a, r in m.inputs.items()} == {2: ("Input three", "input")}
    assert {a: r.name for a, r in m.view("input").registers.items()} == {2: "Input three"}


def test_built_in_maps_round_trip_through_toml(tmp_path):
    paths = sorted(glob.glob("decoders/*/registers.toml")) + ["docs/examples/acme-x1.toml"]
    assert len(paths) >= 4
    for path in paths:
        _round_trip(load_map(path), tmp_path)


# ---- Home Assistant modbus YAML ------------------------------------------------------------------
HA = """\
modbus:
  - name: plant
    type: serial
    port: !secret modbus_port
    baudrate: 9600
    sensors:
      - name: Inverter power
        slave: 3
        address: 40
        input_type: input
        data_type: float32
        swap: word
        unit_of_measurement: W
      - name: Inverter temperature
        slave: 3
        address: 100
        data_type: int16
        scale: 0.1
        precision: 1
        unit_of_measurement: "°C"
      - name: Inverter energy
        device_address: 3
        address: 102
        data_type: uint32
        scale: 0.001
        unit_of_measurement: kWh
      - name: Inverter model
        slave: 3
        address: 110
        data_type: string
        count: 8
      - name: String current
        slave: 3
        address: 200
        data_type: uint16
        scale: 0.01
        unit_of_measurement: A
        slave_count: 2
"""


def test_ha_yaml_map_fields(tmp_path):
    p = tmp_path / "solar.yaml"
    p.write_text(HA, encoding="utf-8")
    [m] = load_model_file(str(p))
    assert m.model_id == "solar"
    r = m.registers
    i = m.inputs  # input_type: input -> the input table only
    assert 40 not in r and (i[40].type, i[40].word_order, i[40].access, i[40].unit, i[40].table) == (
        "f32", "little", "R", "W", "input")
    assert (r[100].type, r[100].scale, r[100].access) == ("s16", 0.1, "RW")
    assert "1 decimals" in r[100].note
    assert (r[102].type, r[102].scale, r[102].unit) == ("u32", 0.001, "kWh")
    assert (r[110].type, r[110].words) == ("str", 8)
    assert [r[a].name for a in (200, 201, 202)] == ["String current [0]", "String current [1]", "String current [2]"]
    assert i[40].section == "solar.yaml line 7 (input)"


def test_ha_yaml_decodes_and_round_trips(tmp_path, capsys):
    p = tmp_path / "solar.yml"
    p.write_text(HA, encoding="utf-8")
    # read 100 (temperature -3.2 °C) and 200..202 (string currents)
    recs = _decode(capsys, p, 3, "solar", fr("030300640001"), fr("030302FFE0"),
                   fr("030300C80003"), fr("03030603E8000004D2"))
    pts = _points(recs)
    assert pts["Inverter temperature"] == (100, -3.2, "°C")
    assert pts["String current [0]"] == (200, 10.0, "A") and pts["String current [2]"] == (202, 12.34, "A")
    [m] = load_model_file(str(p))
    _round_trip(m, tmp_path)


def test_ha_yaml_several_slaves_make_one_model_each(tmp_path, capsys):
    p = tmp_path / "meters.yaml"
    p.write_text("modbus:\n  name: hub\n  sensors:\n"
                 "    - {name: M1 volts, slave: 1, address: 0, scale: 0.1, unit_of_measurement: V}\n"
                 "    - {name: M2 volts, slave: 2, address: 0, scale: 0.1, unit_of_measurement: V}\n")
    maps = load_model_file(str(p))
    assert [(m.model_id, m.registers[0].name) for m in maps] == [("meters-u1", "M1 volts"), ("meters-u2", "M2 volts")]
    code = main(["decode", fr("020300000001"), fr("0203020929"), "--model-file", str(p),
                 "--device", "2=meters-u2", "--device", "1=meters-u1"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "M2 volts=234.5 V" in out


# ---- bad files: one line naming the file and its line, exit 2 ---------------------------------------
BAD = [
    ("m.csv", "address,name\nzz,A\n", "line 2: address 'zz' is not a number (decimal, 0x2524 or 2524H)"),
    ("m.csv", "address,name,type\n1,A,u16\n2,B,u24\n",
     "line 3: unknown type 'u24' (e.g. u16, s16, u32, s32, float32, f64, str, or int16, uint32, float ... "
     "with an order suffix such as _cdab)"),
    ("m.csv", "register;label\n\n1;A\n2;\n", "line 4: name is empty"),
    ("m.csv", "addr,title\n1,A\n", "line 1: the header needs an address and a name column (found: addr, title)"),
    ("m.csv", "# base: 1\naddress,name\n0,A\n", "line 3: address '0': addresses count from 1 here (--map-base 1)"),
    ("m.csv", "# base: 2\naddress,name\n0,A\n", "line 1: base '2': one of 0, 1, modicon"),
    ("m.csv", "address,name\n400001,A\n",
     "line 2: address '400001' is past 0xFFFF (Modicon notation? give --map-base modicon)"),
    ("m.csv", "# base: modicon\naddress,name\n10001,A\n",
     "line 3: address '10001' is not a Modicon register (3xxxx input, 4xxxx holding)"),
    ("m.csv", "address,name,access\n1,A,maybe\n", "line 2: access 'maybe' (one of R, W, RW, reserved)"),
    ("m.csv", "address,name,type\n1,A,string\n", "line 2: a string needs its length in registers (a words column)"),
    ("m.csv", "address,name,scale\n1,A,x\n", "line 2: scale 'x' is not a number"),
    ("m.csv", "address,name\n5,A\n0x5,B\n", "line 3: register 0x0005 listed twice (also line 2)"),
    ("m.csv", "address,name,type\n0xFFFF,A,float32\n", "line 2 (0xFFFF): a f32 here runs past register 0xFFFF"),
    ("m.csv", "address,name\n", "no register rows under the header"),
    ("m.csv", "# only a comment\n", "no header line (address,name,type,scale,unit,access,description)"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - name: a\n        address: [1\n",
     "line 6: not valid YAML (expected ',' or ']', but got '<stream end>')"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - name: a\n        slave: 1\n",
     "line 4: address None must be a register number 0..65535"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - {name: a, address: 1, input_type: coil}\n",
     "line 4: input_type 'coil': only holding and input registers go into a register map"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - {name: a, address: 1, data_type: custom}\n",
     "line 4: data_type custom (a struct format) has no register-map type; split it into sensors"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - {name: a, address: 1, swap: sideways}\n",
     "line 4: swap 'sideways' (one of none, byte, word, word_byte)"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors:\n      - {name: a, address: 1}\n"
               "      - {name: b, address: 1, input_type: holding}\n",
     "line 5: register 0x0001 listed twice (also line 4)"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors: !include sensors.yaml\n",
     "line 2: sensors '!include sensors.yaml' is in another file; give that file (with the hub around it)"),
    ("m.yaml", "modbus:\n  - name: x\n    sensors: []\n", "no modbus sensors in the file"),
    ("m.yaml", "homeassistant:\n  name: x\n", "not a Home Assistant modbus configuration (expected `modbus:` "
                                              "with a list of hubs)"),
    ("m.xlsx", "PK", "unknown register-map format '.xlsx' (one of .toml, .csv, .yaml, .yml)"),
]


@pytest.mark.parametrize("name, text, line", BAD, ids=[f"{b[0]}-{b[2][:40]}" for b in BAD])
def test_bad_map_file_one_line_exit_2(tmp_path, capsys, name, text, line):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    assert one_error(capsys, "decode", "010300000002C40B", "--model-file", p, "--device", "1=m") == f"{p}: {line}"
    with pytest.raises(MapError):
        load_model_file(str(p))


def test_bad_map_base_flag(capsys):
    code, lines = cli(capsys, "decode", "010300000002C40B", "--map-base", "2")
    assert code == 2 and len(lines) == 1 and "--map-base" in lines[0] and "invalid choice" in lines[0]


def test_map_base_travels_to_the_capture_process():
    """`serve` starts its capture as a process of its own: the CSV's address base goes with the map."""
    from sniffer.cli import build_parser
    from sniffer.capture.settings import CaptureSpec

    spec = CaptureSpec.from_args(build_parser().parse_args(
        ["live", "/dev/null", "--model-file", "m.csv", "--map-base", "modicon"]))
    again = CaptureSpec.decode(spec.encode())
    assert (again.model_files, again.map_base) == (("m.csv",), "modicon")


def test_overlapping_rows_and_registers_under_model_are_refused(tmp_path, capsys):
    """Found by an outside review: a u16 inside a float32 loaded silently (CSV, YAML, TOML alike), and
    `registers = [...]` written after [model] gave an empty map."""
    csv = tmp_path / "ov.csv"
    csv.write_text("address,name,type\n0x10,Flow,float32\n0x11,Hidden,u16\n")
    line = one_error(capsys, "decode", "010300000002C40B", "--model-file", csv, "--device", "1=ov")
    assert line == f"{csv}: line 3: register 0x0011 is inside 0x0010 (Flow, a f32 of 2 registers)"
    toml = tmp_path / "late.toml"
    toml.write_text('[model]\nid = "late"\nregisters = [{ addr = 1, name = "a", section = "s" }]\n')
    line = one_error(capsys, "decode", "010300000002C40B", "--model-file", toml, "--device", "1=late")
    assert line.startswith(f"{toml}: [model]: registers sits under [model]")


def test_input_and_holding_at_one_address_keep_their_names(tmp_path, capsys):
    """A meter: input 0000H is a measurement, holding 0000H a setting.  An FC03 read is never named by an
    input sensor, nor an FC04 read by a holding one (found by an outside review: one address space did)."""
    yaml_map = tmp_path / "meter.yaml"
    yaml_map.write_text("modbus:\n  - name: m\n    sensors:\n"
                        "      - {name: Voltage, address: 0, input_type: input, data_type: float32}\n"
                        "      - {name: Demand period, address: 0, data_type: uint16}\n", encoding="utf-8")
    csv_map = tmp_path / "meter.csv"
    csv_map.write_text("# base: modicon\naddress,name,type\n30001,Voltage,float32\n40001,Demand period,u16\n")
    for path, mid in ((yaml_map, "meter"), (csv_map, "meter")):
        recs = _decode(capsys, path, 1, mid, fr("010400000002"), fr("01040443660000"),
                       fr("010300000001"), fr("010302003c"))
        pts = _points(recs)
        assert pts["Voltage"] == (0, 230.0, None) and pts["Demand period"] == (0, 60, None), path
        [m] = load_model_file(str(path))
        _round_trip(m, tmp_path)


# ---------------------------------------------------------------- aliases: bounded expansion
def _laughs(levels: int, inner: str) -> str:
    """A few hundred bytes of nested aliases ("billion laughs"): 9**levels copies of `inner` once expanded."""
    lines = [f"l0: &l0 [{', '.join([inner] * 9)}]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, levels)]
    return "\n".join(lines) + f"\nmodbus:\n  - name: x\n    sensors: *l{levels - 1}\n"


_LOAD_LIMITED = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))
from decoders.mapformats import load_model_file
from decoders.tables import MapError
try:
    load_model_file(sys.argv[1])
except MapError as e:
    print(e)
"""


@pytest.mark.parametrize("inner", ['"lol"', "{name: a, address: 1}"])
def test_nested_aliases_are_refused_before_anything_is_built(tmp_path, inner):
    """9**10 nodes from under 1 kB: refused by counting, in a process that may not take more than 1 GB."""
    import subprocess
    import sys

    p = tmp_path / "laughs.yaml"
    p.write_text(_laughs(10, inner))
    assert p.stat().st_size < 1000
    r = subprocess.run([sys.executable, "-c", _LOAD_LIMITED, str(p)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-500:]
    assert "aliases expand to more than" in r.stdout and len(r.stdout.splitlines()) == 1


def test_an_alias_of_itself_is_one_line(tmp_path):
    p = tmp_path / "loop.yaml"
    p.write_text("modbus: &m\n  - name: x\n    sensors: [*m]\n")
    with pytest.raises(MapError, match="refers to the node that holds it"):
        load_model_file(str(p))


def test_aliases_within_bounds_are_followed(tmp_path):
    """Merging shared defaults into each sensor (a common HA idiom) still loads."""
    p = tmp_path / "merged.yaml"
    sensors = "\n".join(f"      - {{<<: *d, name: s{i}, address: {2 * i}}}" for i in range(200))
    p.write_text(f"defaults: &d {{data_type: uint32, slave: 3, scale: 0.1}}\nmodbus:\n  - name: x\n"
                 f"    sensors:\n{sensors}\n")
    (m,) = load_model_file(str(p))
    assert len(m.registers) == 200 and m.registers[2].type == "u32" and m.registers[2].scale == 0.1
