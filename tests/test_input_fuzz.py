"""Seeded fuzzing of every input file at the command line: never a traceback, one line when refused.

Malformed captures (MCAP, pcap, pcapng, byte CSV, Saleae CSV, random bytes;
pcapng also by its fields: a length, type, interface, time or option of a
block set to a nasty number), bus files and register maps are made from good
ones by a seeded random generator (bit flips, cuts, deleted / inserted /
overwritten / repeated spans; for TOML also nasty values, renamed keys, deep
nesting, non-UTF-8) and driven through sniffer.cli.main in-process, each case
in bounded time (tests/fuzzing.py).  Deterministic: the same cases on every
run (SNIFFER_FUZZ_SEED and SNIFFER_FUZZ_CASES explore others locally).  Marked
`slow`; the surfaces added since (maps in CSV and YAML, query, status,
triggers, --status, ingest) are fuzzed in test_surface_fuzz.py.

What is asserted, per case:
* no "Traceback" anywhere, exit code 0 or 2;
* exit 2: exactly one stderr line, starting "sniffer: error: ";
* FileSource refuses the capture (CaptureError at open) <=> the CLI exits 2
  with one line (captures whose recorded settings the CLI refuses are
  also exit 2, one line);
* FileSource reads it with damage: a Gap is among the events, and the CLI
  replays everything readable, then says it in one line and exits 2;
* a clean read exits 0.
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import pytest
from fuzzing import CASES, SEED, mutate, run
from refdata import SIGROK

from helpers import export

from sniffer.events import Chunk, Gap
from sniffer.formats.mcap.sink import McapSink
from sniffer.events import CaptureError
from sniffer.sources.files import FileSource, open_replay

pytestmark = pytest.mark.slow
CASES_PER_FORMAT = CASES
TOML_CASES = 2 * CASES_PER_FORMAT
WIZ = SIGROK / "wizmodbus.bytes.csv"

BUS = """[serial]
baud = 9600
parity = "N"
stopbits = 1
protocol = "modbus-rtu"

[units]
1 = "generic"
2 = "a510"

[timeouts_ms]
1 = 250
"""

MAP = """registers = [
  { addr = 0x0000, id = "P-01", name = "Speed", type = "u16", scale = 0.1, unit = "Hz", access = "RW", section = "1" },
  { addr = 0x0001, id = "", name = "Status", type = "u16", bits = "status", access = "R", section = "2" },
  { addr = 0x0002, id = "", name = "Fault", type = "u16", enum = "fault", access = "R", section = "3" },
  { addr = 0x0010, id = "", name = "Slot", type = "u32", count = 4, stride = 2, access = "R", section = "4" },
]

[model]
id = "fuzz"
name = "Fuzz drive"
max_registers_per_request = 16
broadcast_registers = [0]

[exceptions]
0x41 = { name = "BUSY", text = "busy" }

[enums.fault]
"0" = "none"
"0x01" = { text = "OC", detail = "over current" }

[bits.status]
"0" = "run"
"1-2" = { name = "mode", values = { "0" = "a", "1" = "b" } }
"""

NASTY = ["nan", "inf", "-inf", "-1", "0", "1e308", "100000000", '"x"', '""', "true", "[5]", "[]", "{}",
         "{ a = 1 }", '"0x10"', "0x10", "1.5", "99999999999999999999", '"' + "x" * 300 + '"',
         "[" * 40 + "]" * 40, '"a510"', "65535", "4294967296"]


# -- the seed files -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> dict[str, bytes]:
    d = tmp_path_factory.mktemp("seeds")
    out = {"csv": WIZ.read_bytes()}
    info, events = open_replay(str(WIZ))
    info.baud = 9600
    sink = McapSink(d / "wiz.mcap", flush_interval_s=0, seal_interval_s=0)  # a chunk per event: damage loses little
    sink.start(info)
    for ev in events:
        sink.raw(ev)
    sink.close()
    out["mcap"] = (d / "wiz.mcap").read_bytes()
    for ext in ("pcap", "pcapng"):
        export(WIZ, "pcap", d / f"wiz.{ext}", "--baud", "9600")
        out[ext] = (d / f"wiz.{ext}").read_bytes()
    rows = WIZ.read_text().splitlines()[1:]
    out["saleae"] = ("name,type,start_time,duration,data\n" + "".join(
        f'"Async Serial {ch}","data",{t},0.000937,0x{b.upper()}\n'
        for t, ch, b, _f in (r.split(",") for r in rows))).encode()
    return out


NASTY_U32 = (0, 1, 3, 4, 11, 12, 13, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, 0xFFFFFFFC, 0x1000000, 65535, 65536)


def mutate_pcapng_field(data: bytes, rng: random.Random) -> bytes:
    """One 4-byte field of one block (its type, length, interface, time, captured or original length, an
    option) set to a nasty number, or nudged by a few: structure a byte mutation rarely reaches."""
    blocks, pos = [], 0
    while pos + 12 <= len(data):
        blocks.append(pos)
        pos += max(12, struct.unpack_from("<I", data, pos + 4)[0])
    at = rng.choice(blocks) + 4 * rng.randrange(7)  # a packet block's header: its bytes start at 28
    if at + 4 > len(data):
        return mutate(data, rng)
    d = bytearray(data)
    old = struct.unpack_from("<I", d, at)[0]
    new = rng.choice(NASTY_U32) if rng.random() < 0.6 else (old + rng.randint(-8, 8)) % (1 << 32)
    struct.pack_into("<I", d, at, new)
    return bytes(d)


def mutate_toml(text: str, rng: random.Random) -> bytes:
    lines = text.splitlines()
    kind = rng.randrange(8)
    k = rng.randrange(len(lines))
    if kind == 0 and "=" in lines[k]:
        key, _, _value = lines[k].partition("=")
        lines[k] = f"{key}= {rng.choice(NASTY)}"
    elif kind == 1 and "=" in lines[k]:
        lines[k] = lines[k].replace(lines[k].split("=")[0].strip(), rng.choice(["x", "1", "300", "-1", "unit"]), 1)
    elif kind == 2:
        del lines[k]
    elif kind == 3:
        lines.insert(k, lines[rng.randrange(len(lines))])
    elif kind == 4:
        lines.insert(rng.randrange(len(lines) + 1), rng.choice(["[unit]", "[serial]", "[x.y]", "junk", "= 1"]))
    elif kind == 5:
        lines.append("z = " + "[" * 3000 + "]" * 3000)
    elif kind == 6:
        return mutate(("\n".join(lines) + "\n").encode(), rng)
    else:
        return ("\n".join(lines[:k]) + "\n").encode() + b"\xff\xfe" + ("\n".join(lines[k:]) + "\n").encode()
    return ("\n".join(lines) + "\n").encode()


# -- running them ---------------------------------------------------------------------------------
def cli(capsys, args) -> tuple[int, list[str]]:
    return run(capsys, args)


# losses that need no Gap: nothing readable comes after them, or no byte was lost
NO_GAP_NEEDED = ("cut off", "ends inside", "reorder window", "not a serial capture", "not listed")


def source_verdict(path: Path) -> tuple[str, bytes]:
    """'refused', 'damaged' (read with damage: a Gap was yielded where input was lost) or 'clean'; the bytes."""
    src = FileSource(path)
    try:
        src.open()
        events = list(src.events())
    except CaptureError:
        return "refused", b""
    data = b"".join(e.data for e in events if type(e) is Chunk)
    if not src.damage:
        return "clean", data
    if not any(type(e) is Gap for e in events) and any(type(e) is Chunk for e in events):
        assert all(any(w in line for w in NO_GAP_NEEDED) for line in src.damage), src.damage
    return "damaged", data


@pytest.mark.parametrize("fmt", ["mcap", "pcap", "pcapng", "pcapng-fields", "csv", "saleae", "random"])
def test_malformed_captures(tmp_path, capsys, seeds, fmt):
    rng = random.Random(f"{SEED}-{fmt}")
    verdicts: dict[str, int] = {}
    if fmt == "pcapng-fields":
        (tmp_path / "seed.pcapng").write_bytes(seeds["pcapng"])
        clean = source_verdict(tmp_path / "seed.pcapng")[1]
    for case in range(CASES_PER_FORMAT):
        ext = {"random": "bin", "pcapng-fields": "pcapng"}.get(fmt, fmt)
        path = tmp_path / f"case{case}.{ext}"
        if fmt == "random":
            data = rng.randbytes(rng.randint(1, 3000))
        elif fmt == "pcapng-fields":
            data = mutate_pcapng_field(seeds["pcapng"], rng)
        else:
            data = mutate(seeds[fmt], rng)
        path.write_bytes(data)
        verdict, got = source_verdict(path)
        if fmt == "pcapng-fields" and verdict == "clean":  # a header changed, no word: every byte is there
            assert got == clean, (case, "bytes lost without a word")
        code, lines = cli(capsys, ["replay", path, "--baud", "9600"])
        if verdict in ("refused", "damaged"):  # damaged: everything readable replayed, then one line, exit 2
            assert code == 2, (case, lines)
        if verdict == "damaged":
            assert "input damaged" in lines[0], lines
        if verdict == "clean":
            assert code == 0, (case, lines)
        verdicts[verdict] = verdicts.get(verdict, 0) + 1
    if fmt != "random":  # the mutations reach damage, or the test proves little
        assert verdicts.get("damaged", 0) > 0, verdicts
    if fmt == "random":
        assert verdicts == {"refused": CASES_PER_FORMAT}


def test_malformed_bus_files(tmp_path, capsys):
    rng = random.Random(f"{SEED}-bus")
    codes = []
    for case in range(TOML_CASES):
        bus = tmp_path / f"bus{case}.toml"
        bus.write_bytes(mutate_toml(BUS, rng))
        code, _lines = cli(capsys, ["replay", WIZ, "--baud", "9600", "--bus", bus])
        codes.append(code)
    assert 0 in codes and 2 in codes


def test_malformed_register_maps(tmp_path, capsys):
    rng = random.Random(f"{SEED}-map")
    codes = []
    for case in range(TOML_CASES):
        m = tmp_path / f"map{case}.toml"
        m.write_bytes(mutate_toml(MAP, rng))
        code, _lines = cli(capsys, ["decode", "010300000002C40B", "010304000100022A32",
                                    "--model-file", m, "--device", "1=fuzz"])
        codes.append(code)
    assert 0 in codes and 2 in codes
