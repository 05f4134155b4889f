"""Bad input files at the command line: one `sniffer: error:` line naming the file and the place, exit 2.

Capture files (FIFO, directory, empty, garbage, CSV rows that cannot be a
time or a byte), bus files and register maps, driven through
sniffer.cli.main in-process.  The exact line is asserted: it is what a user
reads.
"""

from __future__ import annotations

import os
import threading

import pytest

from decoders.tables import MapError, load_map
from sniffer.capture.busfile import BusFileError, load_bus_file
from sniffer.cli import main
from sniffer.formats.timeparse import seconds_to_ns

HEADER = "t_s,channel,byte_hex,flags\n"
GOOD_ROW = "0.100000,RX,01,\n"


def cli(capsys, *args) -> tuple[int, list[str]]:
    code = main([str(a) for a in args])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, [line for line in err.splitlines() if line.strip()]


def one_error(capsys, *args) -> str:
    code, lines = cli(capsys, *args)
    assert code == 2 and len(lines) == 1, (code, lines)
    assert lines[0].startswith("sniffer: error: ")
    return lines[0][len("sniffer: error: "):]


# -- times -------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, ns", [
    ("0.000937", 937_000), ("12", 12_000_000_000), (" 1.5 ", 1_500_000_000), (".5", 500_000_000),
    ("1.0000000005", 1_000_000_001), ("1.0000000004999", 1_000_000_000), ("1.5e-3", 1_500_000),
    ("-2.25", -2_250_000_000), ("9223372036.854775807", 2**63 - 1),
])
def test_seconds_to_ns_exact(text, ns):
    assert seconds_to_ns(text) == ns


@pytest.mark.parametrize("text", [
    "", ".", "-", "1e", "e5", "1e999999", "1e5000", "-1e5000", "nan", "NaN", "inf", "-Infinity", "1.2.3", "0x10",
    "1_000", "١.٥", "9223372036.854775808", "1" * 100, "1e-999999",
])
def test_seconds_to_ns_refuses(text):
    with pytest.raises(ValueError):
        seconds_to_ns(text)


# -- capture files -------------------------------------------------------------------------------
def test_fifo_is_refused_without_blocking(tmp_path, capsys):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    fifo = tmp_path / "capture.csv"
    os.mkfifo(fifo)
    out = []
    t = threading.Thread(target=lambda: out.append(one_error(capsys, "replay", fifo, "--baud", "9600")), daemon=True)
    t.start()
    t.join(20)
    assert not t.is_alive(), "replaying a FIFO blocked"
    assert out == [f"{fifo}: not a regular file (a FIFO): reading it would block forever or never end"]


def test_directory_empty_and_garbage(tmp_path, capsys):
    # a folder is read as a rotated capture's segments (sources/segset.py): this one holds none
    assert one_error(capsys, "replay", tmp_path) == f"{tmp_path}: no capture files there (no segments, no .mcap)"
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert one_error(capsys, "replay", empty) == f"{empty}: empty file"
    junk = tmp_path / "junk.bin"
    junk.write_bytes(os.urandom(4096).replace(b"\x89", b"\x00"))
    assert one_error(capsys, "replay", junk).startswith(f"{junk}: unknown capture format")


@pytest.mark.parametrize("row, why", [
    ("1e999999,RX,01,", "time out of range: '1e999999'"),
    ("1e5000,RX,01,", "time out of range: '1e5000'"),
    ("1e,RX,01,", "not a number of seconds: '1e'"),
    ("nan,RX,01,", "not a number of seconds: 'nan'"),
    ("inf,RX,01,", "not a number of seconds: 'inf'"),
    ("-0.5,RX,01,", "negative time"),
    ("0.5,RX,100,", "the byte is not 00..ff"),
    ("0.5,RX,zz,", "the byte is not 00..ff"),
    ("0.5,RX,01,sparkle", "unknown flag 'sparkle' (framing, parity or empty)"),
    ("0.5,RX", "too few columns"),
])
def test_csv_whose_only_row_is_bad(tmp_path, capsys, row, why):
    p = tmp_path / "one.csv"
    p.write_text(HEADER + row + "\n")
    assert one_error(capsys, "replay", p, "--baud", "9600") == \
        f"{p}:2: bad row {row!r} ({why}); no row of this byte CSV is readable"


def test_csv_field_over_the_csv_limit(tmp_path, capsys):
    p = tmp_path / "huge.csv"
    p.write_text(HEADER + "0.5,RX," + "a" * 200_000 + ",\n")
    assert one_error(capsys, "replay", p, "--baud", "9600") == \
        f"{p}:2: bad row (field larger than field limit (131072)); no row of this byte CSV is readable"


def test_long_bad_field_is_quoted_short(tmp_path, capsys):
    p = tmp_path / "long.csv"
    p.write_text(HEADER + "0.5,RX," + "a" * 100_000 + ",\n")
    msg = one_error(capsys, "replay", p, "--baud", "9600")
    assert msg.startswith(f"{p}:2: bad row '0.5,RX,aaaa") and "... (100,008 characters) (the byte is not 00..ff)" in msg
    assert len(msg) < 360 + len(str(p))


def test_csv_export_cut_mid_row_is_the_only_row(tmp_path, capsys):
    p = tmp_path / "cut.csv"
    p.write_text(HEADER + "0.5,R")
    assert one_error(capsys, "replay", p, "--baud", "9600") == (
        f"{p}:2: bad row '0.5,R' (too few columns; the file ends mid-row (export cut short?)); "
        "no row of this byte CSV is readable")


def test_saleae_whose_only_row_is_bad(tmp_path, capsys):
    p = tmp_path / "logic2.csv"
    p.write_text('name,type,start_time,duration,data\n"A","data",1e999999,0.001,0x01\n')
    assert one_error(capsys, "replay", p, "--baud", "9600") == (
        f"{p}:2: bad row 'A,data,1e999999,0.001,0x01' (time out of range: '1e999999'); "
        "no row of this Saleae export is readable")


def test_csv_header_only(tmp_path, capsys):
    p = tmp_path / "header.csv"
    p.write_text(HEADER)
    assert one_error(capsys, "replay", p, "--baud", "9600") == f"{p}: no serial bytes in this byte CSV (no data rows)"


# -- bus files -----------------------------------------------------------------------------------
BUS_CASES = [
    ("serial = 5", "serial must be a table [serial], not 5"),
    ('[serial]\nbaud = "fast"', "[serial] baud must be an integer 50..4000000, not 'fast'"),
    ("[serial]\nbaud = 10", "[serial] baud must be an integer 50..4000000, not 10"),
    ("[serial]\nbaud = 9600.0", "[serial] baud must be an integer 50..4000000, not 9600.0"),
    ('[serial]\nparity = "X"', "[serial] parity must be \"N\", \"E\" or \"O\", not 'X'"),
    ("[serial]\nstopbits = 3", "[serial] stopbits must be 1 or 2, not 3"),
    ("[serial]\ndatabits = 5", "[serial] databits must be 7 or 8, not 5"),
    ('[serial]\nprotocol = "can-bus"',
     "[serial] protocol 'can-bus' is not one of modbus-rtu, modbus-ascii, pd-rtu, pd-ascii"),
    ("[serial]\nbuad = 9600", "[serial] unknown keys ['buad'] (known: baud, parity, stopbits, databits, protocol)"),
    ('[unit]\n1 = "a510"',
     "unknown tables or keys ['unit'] (known: serial, units, timeouts_ms, parameters, links, broadcast)"),
    ('[units]\n300 = "a510"', "[units] key '300' is not a unit number 0..255"),
    ('[units]\nx = "a510"', "[units] key 'x' is not a unit number 0..255"),
    ("[units]\n1 = 5", '[units] 1 must be a model id string (e.g. "a510"), not 5'),
    ("[timeouts_ms]\n1 = nan", "[timeouts_ms] 1 must be a number of milliseconds 0..86400000, not nan"),
    ("[timeouts_ms]\n1 = -5", "[timeouts_ms] 1 must be a number of milliseconds 0..86400000, not -5"),
    ('[timeouts_ms]\n1 = "soon"', "[timeouts_ms] 1 must be a number of milliseconds 0..86400000, not 'soon'"),
    ("x = " + "[" * 5000 + "]" * 5000, "nested too deeply to be a bus file or register map"),
    ("x = " + "{a = " * 3000 + "1" + "}" * 3000, "nested too deeply to be a bus file or register map"),
    ("[serial\nbaud = 9600", "not valid TOML (Expected ']' at the end of a table declaration (at line 1, column 8))"),
]


@pytest.mark.parametrize("text, line", BUS_CASES, ids=[c[1][:40] for c in BUS_CASES])
def test_bad_bus_file(tmp_path, capsys, text, line):
    bus = tmp_path / "bus.toml"
    bus.write_text(text + "\n")
    assert one_error(capsys, "decode", "010300000002C40B", "--bus", bus) == f"{bus}: {line}"
    with pytest.raises(BusFileError):
        load_bus_file(str(bus))


def test_bus_file_not_utf8_or_huge(tmp_path, capsys):
    bus = tmp_path / "bus.toml"
    bus.write_bytes(b"[serial]\nbaud = 9600\n# \xff\xfe\n")
    assert one_error(capsys, "decode", "010300000002C40B", "--bus", bus) == f"{bus}: not UTF-8 text (line 3, byte 23)"
    bus.write_bytes(b"#" * (17 << 20))
    assert one_error(capsys, "decode", "010300000002C40B", "--bus", bus) == \
        f"{bus}: over 16 MB: not a bus file or register map"


@pytest.mark.parametrize("command", [["decode", "010300000002C40B"], ["replay", "CAPTURE"],
                                     ["live", "/dev/nonexistent-port"], ["export", "CAPTURE", "--to", "jsonl"]])
@pytest.mark.parametrize("flag, first, second", [("--bus", "a.toml", "b.toml"), ("--baud", "9600", "19200"),
                                                 ("--parity", "E", "N"), ("--out", "x.mcap", "y.mcap")])
def test_a_single_value_flag_given_twice_is_refused(tmp_path, capsys, command, flag, first, second):
    """The second would silently replace the first (a link captured at the wrong settings): one line, exit 2,
    before any file is read or written."""
    capture = tmp_path / "c.csv"
    capture.write_text(HEADER + GOOD_ROW)
    argv = [str(capture) if a == "CAPTURE" else a for a in command]
    if (flag == "--out" and command[0] in ("decode", "replay")) or (flag == "--parity" and command[0] == "decode"):
        return  # flags these commands do not have
    paths = [str(tmp_path / v) if flag in ("--bus", "--out") else v for v in (first, second)]
    line = one_error(capsys, *argv, flag, paths[0], flag, paths[1])
    assert line == f"{flag} given twice ({paths[0]!r} and {paths[1]!r}): it takes one value"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.csv"]  # nothing written


def test_repeatable_flags_still_repeat(capsys):
    code, lines = cli(capsys, "decode", "--device", "1=a510", "--device", "2=tds-v8", "010300000002C40B")
    assert code == 0 and not lines


def test_good_bus_file_still_loads(tmp_path):
    bus = tmp_path / "bus.toml"
    bus.write_text('[serial]\nbaud = 19200\nparity = "e"\nstopbits = 2\nprotocol = "pd-rtu"\n'
                   '[units]\n1 = "a510"\n"2" = "tds-v8"\n[timeouts_ms]\n1 = 250\n2 = 12.5\n')
    b = load_bus_file(str(bus))
    assert (b.baud, b.parity, b.stopbits, b.protocol) == (19200, "E", 2, "pd-rtu")
    assert b.devices == {1: "a510", 2: "tds-v8"} and b.timeouts_ms == {1: 250.0, 2: 12.5}


# -- register maps -------------------------------------------------------------------------------
MODEL = '[model]\nid = "x"\n'
MAP_CASES = [
    ("registers = [5]\n" + MODEL, "register row 1: must be a table, not 5"),
    ('registers = [{ addr = "0x10", name = "a" }]\n' + MODEL,
     "register row 1: addr must be an integer in 0..65535, not '0x10'"),
    ('registers = [{ addr = 70000, name = "a" }]\n' + MODEL,
     "register row 1: addr must be an integer in 0..65535, not 70000"),
    ('registers = [{ addr = 1 }]\n' + MODEL, "register row 1: bad keys addr/name missing"),
    ('registers = [{ addr = 1, name = "a", colour = "red" }]\n' + MODEL, "register row 1: bad keys ['colour']"),
    ('registers = [{ addr = 1, name = 7 }]\n' + MODEL,
     "register row 1 (0x0001): name must be a non-empty string, not 7"),
    ('registers = [{ addr = 1, name = "a", count = 100000000 }]\n' + MODEL,
     "register row 1 (0x0001): count must be an integer in 1..65536, not 100000000"),
    ('registers = [{ addr = 0x100, name = "a", count = 1000, stride = 100 }]\n' + MODEL,
     "register row 1 (0x0100): count 1000 x stride 100 runs past register 0xFFFF"),
    ('registers = [{ addr = 0xFFFF, name = "a", type = "u32" }]\n' + MODEL,
     "register row 1 (0xFFFF): a u32 here runs past register 0xFFFF"),
    ('registers = [{ addr = 0, name = "a", count = 65536 }, { addr = 0, name = "b", count = 65536 }]\n' + MODEL,
     "registers: 131072 registers: more than the 65536 addresses a unit has"),
    ('registers = [{ addr = 1, name = "a", type = "u128" }]\n' + MODEL,
     "register row 1 (0x0001): unknown type 'u128' (one of u16, s16, u32, s32, f32, u64, s64, f64, str)"),
    ('registers = [{ addr = 1, name = "a", type = "str" }]\n' + MODEL,
     "register row 1 (0x0001): a str needs words = 1..125 (registers of text), not none"),
    ('registers = [{ addr = 1, name = "a", type = "f32", words = 4 }]\n' + MODEL,
     "register row 1 (0x0001): words = 4, but a f32 takes 2"),
    ('registers = [{ addr = 1, name = "a", type = "str", words = 2, word_order = "little" }]\n' + MODEL,
     "register row 1 (0x0001): word_order does not apply to a str (its characters follow the addresses)"),
    ('registers = [{ addr = 1, name = "a", type = "u32", byte_order = "middle" }]\n' + MODEL,
     "register row 1 (0x0001): byte_order 'middle' (big or little)"),
    ('registers = [{ addr = 0xFFFE, name = "a", type = "str", words = 3 }]\n' + MODEL,
     "register row 1 (0xFFFE): a str here runs past register 0xFFFF"),
    ('[model]\nid = "x"\nword_order = "mixed"', "[model]: word_order 'mixed' (big or little)"),
    ('registers = [{ addr = 1, name = "a", scale = nan }]\n' + MODEL,
     "register row 1 (0x0001): scale must be a finite number, not nan"),
    ('registers = [{ addr = 1, name = "a", scale = "0.1" }]\n' + MODEL,
     "register row 1 (0x0001): scale must be a finite number, not '0.1'"),
    ('registers = [{ addr = 1, name = "a", access = "X" }]\n' + MODEL,
     "register row 1 (0x0001): access 'X' (one of R, RW, W, reserved)"),
    ('registers = [{ addr = 1, name = "a", scale_by = { addr = 2, full = 0 } }]\n' + MODEL,
     "register row 1 (0x0001): scale_by needs addr and a positive number full"),
    ("[model]\nid = 5", "[model]: id must be a non-empty string, not 5"),
    ('[model]\nname = "x"\n[enums.e]\n"1" = 5', "[enums.e] 1: must be a table, not 5"),
    ('[model]\nid = "x"\nbroadcast_registers = ["a"]',
     "[model]: broadcast_registers must be a list of integers, not ['a']"),
    (MODEL + "[enums.e]\nabc = \"x\"", "[enums.e]: key 'abc' is not a number (decimal or 0x.. hex)"),
    (MODEL + "[enums.e]\n1 = 5", "[enums.e] 1: must be a table, not 5"),
    (MODEL + "[enums.e]\n1 = { detail = \"d\" }", "[enums.e] 1: text missing"),
    (MODEL + '[bits.b]\n"64" = "x"', "[bits.b]: key '64': bits must be 0..63, low first"),
    (MODEL + '[bits.b]\n"x-y" = "x"', "[bits.b]: key 'x-y' is not a bit number or lo-hi range"),
    (MODEL + '[bits.b]\n"0" = { name = "n", values = { on = "x" } }',
     "[bits.b] 0 values: key 'on' is not a number (decimal or 0x.. hex)"),
    (MODEL + '[exceptions]\n"0x1ff" = "x"', "[exceptions]: key '0x1ff' is outside 0..255"),
    ('[modle]\nid = "x"', "top level: unknown keys ['modle'] (known: registers, model, enums, bits, exceptions)"),
    # what the table lint says of the built-in maps holds for a user's map too (an outside review found
    # these loaded silently): one line, the first problem, how many more
    ('registers = [{ addr = 1, name = "a", type = "f32", enum = "e" }]\n' + MODEL + '[enums.e]\n"1" = "one"',
     "0x0001: a f32 takes no enum"),
    ('registers = [{ addr = 1, name = "a", type = "u32", bits = "b" }]\n' + MODEL + '[bits.b]\n"3-40" = "x"',
     "0x0001: bits 'b' field 'x' past bit 31"),
    ('registers = [{ addr = 1, name = "a", enum = "zz" }]\n' + MODEL, "0x0001: enum 'zz' not defined"),
    ('registers = [{ addr = 1, name = "a", scale = 0 }, { addr = 2, name = "b", min = 5, max = 1 }]\n' + MODEL,
     "0x0001: scale 0 makes every value 0 (and 1 more)"),
    ('registers = [{ addr = 1, name = "a", type = "str", words = 2, scale = 0.1 }]\n' + MODEL,
     "0x0001: a str takes no scale"),
    ('registers = [{ addr = 1, name = "a", min = 70000 }]\n' + MODEL, "0x0001: min 70000 is outside a u16 (0..65535)"),
    ('registers = [{ addr = 1, name = "a", type = "s16", default = 40000 }]\n' + MODEL,
     "0x0001: default 40000 is outside a s16 (-32768..32767)"),
    ('registers = [{ addr = 1, name = "a", table = "input", access = "RW" }]\n' + MODEL,
     "0x0001: access RW on an input register (Modbus input registers are read-only)"),
    ('registers = [{ addr = 1, name = "a", table = "coil" }]\n' + MODEL,
     "register row 1 (0x0001): table 'coil' (holding or input)"),
]


@pytest.mark.parametrize("text, line", MAP_CASES, ids=[c[1][:40] for c in MAP_CASES])
def test_bad_register_map(tmp_path, capsys, text, line):
    m = tmp_path / "map.toml"
    m.write_text(text + "\n")
    assert one_error(capsys, "decode", "010300000002C40B", "--model-file", m, "--device", "1=x") == f"{m}: {line}"
    with pytest.raises(MapError):
        load_map(m)


def test_good_register_map_with_counts_and_tables(tmp_path, capsys):
    m = tmp_path / "map.toml"
    m.write_text('registers = [{ addr = 0x10, name = "Slot", count = 3, stride = 2, enum = "e" },'
                 ' { addr = 0, name = "W", type = "u32", bits = "b", scale = 0.5 }]\n'
                 '[model]\nid = "mine"\n[enums.e]\n"0x01" = "one"\n"2" = { text = "two", detail = "2" }\n'
                 '[bits.b]\n"0" = "run"\n"4-5" = { name = "mode", values = { "0" = "a", "1" = "b" } }\n'
                 '[exceptions]\n0x41 = "vendor"\n')
    rm = load_map(m)
    assert sorted(rm.registers) == [0, 0x10, 0x12, 0x14] and rm.registers[0x12].name == "Slot [1]"
    assert rm.enum_text("e", 1) == "one" and rm.enum_text("e", 2) == "two — 2"
    assert rm.exceptions[0x41]["name"] == "vendor" and rm.bits_text("b", 0b010001) == "run, mode=b"
    code, lines = cli(capsys, "decode", "010300100001", "--model-file", m, "--device", "1=mine")
    assert code == 0 and lines == []


def test_a_user_map_may_not_take_the_generic_id(tmp_path, capsys):
    m = tmp_path / "g.toml"
    m.write_text('registers = [{ addr = 1, name = "a" }]\n[model]\nid = "generic"\n')
    assert one_error(capsys, "decode", "010300000002C40B", "--model-file", m) == (
        f"{m}: model id 'generic' is the fallback for every unit; give the map its own id")


def test_a_toml_map_without_an_id_takes_its_file_stem(tmp_path, capsys):
    """As a CSV or YAML map does (issue 10 section 4): the model id is the file's stem unless it names one."""
    m = tmp_path / "pump.toml"
    m.write_text('registers = [{ addr = 0, name = "Speed", unit = "rpm" }]\n')
    assert load_map(m).model_id == "pump"
    code = main(["decode", "--model-file", str(m), "--device", "1=pump", "010300000001840A", "0103020064B9AF"])
    out = capsys.readouterr().out
    assert code == 0 and "pump" in out and "Speed=100 rpm" in out


# -- [model]: every key checked as a row's fields are (decoders/model_info.py) ---------------------
MODEL_KEY_CASES = [
    ("function_codes = 3", "[model]: function_codes must be a list of integers 1..255, not 3"),
    ("function_codes = [0x103]", "[model]: function_codes must be a list of integers 1..255, not [259]"),
    ("function_code = [3]", "[model]: unknown key 'function_code' (did you mean function_codes?)"),
    ('mode_register = { addr = 32 }', "[model]: mode_register must be { addr, bit (0..15) }, not {'addr': 32}"),
    ('max_frame_bytes = "80"', "[model]: max_frame_bytes must be an integer in 4..65536, not '80'"),
    ("unit_addresses = [1]", "[model]: unit_addresses must be [lowest, highest] unit address (0..255), not [1]"),
    ("not_available = [{ addr = 1 }]",
     "[model]: not_available must be a list of { addr, raw (0..0xFFFF), text }, not [{'addr': 1}]"),
]


@pytest.mark.parametrize("line, said", MODEL_KEY_CASES, ids=[c[0] for c in MODEL_KEY_CASES])
def test_a_model_key_of_the_wrong_kind_is_one_line(tmp_path, capsys, line, said):
    m = tmp_path / "map.toml"
    m.write_text(f'registers = [{{ addr = 0, name = "a" }}]\n[model]\nid = "x"\n{line}\n')
    assert one_error(capsys, "decode", "010300000002C40B", "--model-file", m, "--device", "1=x") == f"{m}: {said}"


WRONG_KINDS = ["3", "-1", "1.5", '"x"', "true", '["a"]', "[3]", "[[1, 2]]", "[1, 300]", "{ a = 1 }",
               "{ addr = 1, bit = 99 }", '[{ addr = 1, raw = 2, text = 3 }]']


def test_every_model_key_read_by_the_code_is_checked_before_it_is_used(tmp_path, capsys):
    """Every key a decoder, the identifier or the simulator reads, given every kind of wrong value: the map
    loads (the value fits) and a decode, a replay and the identifier run; or one line naming the key."""
    from decoders.model_info import KEYS as MODEL_KEYS

    seen = {"loaded": 0, "refused": 0}
    for key in MODEL_KEYS:
        for value in WRONG_KINDS:
            m = tmp_path / "map.toml"
            m.write_text('registers = [{ addr = 0, name = "a" }]\n[model]\n'
                         + ('id = "x"\n' if key != "id" else "") + f"{key} = {value}\n")
            code, lines = cli(capsys, "decode", "010300000002C40B", "0103040001000290", "011000000001",
                              "--model-file", m, "--device", "1=x")
            assert code in (0, 2), (key, value, lines)
            if code == 2:
                assert len(lines) == 1 and lines[0].startswith(f"sniffer: error: {m}: "), (key, value, lines)
                assert key in lines[0] or "id" in lines[0], (key, value, lines)
                seen["refused"] += 1
            else:
                seen["loaded"] += 1
    assert seen["refused"] > len(MODEL_KEYS) * 5 and seen["loaded"] > 0


def test_a_csv_map_field_over_the_csv_limit_is_one_line(tmp_path, capsys):
    m = tmp_path / "meter.csv"
    m.write_text("address,name,type\n0,Voltage,u16\n1," + "V" * 200_000 + ",u16\n")
    assert one_error(capsys, "decode", "010300000002C40B", "--model-file", m, "--device", "1=meter") == (
        f"{m}: line 3: not a CSV row (field larger than field limit (131072))")


NESTED = {"5000 parentheses": "(" * 5000 + "crc" + ")" * 5000, "5000 nots": "not " * 5000 + "crc",
          "100000 !": "!" * 100_000 + "crc", "rates in rates": "rate(" * 3 + "crc" + ")>1/s" * 3,
          "101 parentheses": "(" * 101 + "crc" + ")" * 101}


@pytest.mark.parametrize("nest", list(NESTED.values()), ids=list(NESTED))
def test_a_trigger_nested_too_deep_is_one_line(tmp_path, capsys, nest):
    from refdata import SIGROK

    msg = one_error(capsys, "replay", SIGROK / "wizmodbus.bytes.csv", "--baud", "9600", "--trigger", nest,
                    "--windows", tmp_path)
    assert "filter error at column" in msg and len(msg) < 400, msg
