"""Seeded fuzzing of the inputs and options added since test_input_fuzz.py: never a traceback, never a hang.

Register maps in CSV and Home Assistant YAML, `query` SQL, `status` files, `--trigger` filters,
`--on-trigger` commands and their timeout, `--status` paths, and `ingest` over a folder of mutated
captures into a dataset whose own files (dataset.json, the manifest, _staging) are mutated too.
Each is made from a good one by a seeded generator (tests/fuzzing.py: the same cases every run,
SNIFFER_FUZZ_SEED / SNIFFER_FUZZ_CASES for others) and run through sniffer.cli.main in-process,
each case within fuzzing.CASE_S.  Per case: no "Traceback", exit 0 or 2 (`status`: 1 too, a
capture not running; `ingest`: 1 when the dataset cannot be written); exit 2 is one line
"sniffer: error: ..." (`ingest`: one per capture it could not take in, then its total); any other
stderr line is the sniffer's own ("sniffer: ...").  Each generator must reach both outcomes, or
it proves little.  Not fuzzed here: YAML alias bombs, --on-trigger commands that flood or leave
children (sniffer's bounds on those are tested where they are built).
"""

from __future__ import annotations

import json
import random
import shutil
from pathlib import Path

import pytest
from fuzzing import CASES, SEED, mutate, run
from refdata import SIGROK

from sniffer.dataset.query import PRESETS

pytestmark = pytest.mark.slow
WIZ = SIGROK / "wizmodbus.bytes.csv"
SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"
FRAMES = ["010300000002C40B", "0103040001000290", "0104000A0002", "011000140002040001000A"]


def outcomes(codes: list[int]) -> None:
    assert 0 in codes and 2 in codes, sorted(set(codes))


# -- maps: CSV and Home Assistant YAML ------------------------------------------------------------
CSV_MAP = """# model: fuzz
# name: Fuzz meter
address,name,type,scale,unit,access,description,id,word_order,words,min,max,default,section,table
0x0000,Voltage,float32,,V,R,Line volts,,,,,,,1,input
2,Current,u16,0.01,A,R,,,,,,,,2,holding
4,Energy,uint32_cdab,0.1,kWh,R,,,,,,,,3,
10,Serial,string,,,R,,,,4,,,,4,
20,Setpoint,int16,0.5,Hz,RW,,P-01,,,0,100,50,5,
0x14H,Mode,u16,,,RW,,,,,,,,6,input
"""
CSV_NASTY = ["", "-1", "0", "1e308", "nan", "inf", "0x", "0x10000", "65536", "99999999999999999999999", "x" * 300,
             "x" * 140_000, '"unclosed', 'a"b', "\x00", "a;b", "1,5", "ABCD", "float32_zz", "string", "40001", "30001",
             "reserved", "R/W", "holding", "coil", "1.5", "-0", "٣", "\t", "#", "'"]


def mutate_csv(text: str, rng: random.Random) -> bytes:
    lines = text.splitlines()
    k = rng.randrange(len(lines))
    kind = rng.randrange(8)
    if kind == 7:  # a field over csv.field_size_limit()
        huge = "x" * rng.choice([131_073, 300_000])
        lines.insert(rng.randrange(1, len(lines) + 1), f"{rng.randrange(99)},{huge},u16")
    elif kind <= 1 and "," in lines[k]:
        cells = lines[k].split(",")
        cells[rng.randrange(len(cells))] = rng.choice(CSV_NASTY)
        lines[k] = ",".join(cells)
    elif kind == 2:
        del lines[k]
    elif kind == 3:
        lines.insert(k, lines[rng.randrange(len(lines))])
    elif kind == 4:
        lines.insert(rng.randrange(len(lines) + 1), rng.choice(["# base: 1", "# base: modicon", "# base: 7",
                                                                 "# model:", "address;name;type", ";;;;", ""]))
    elif kind == 5:
        lines = [line.replace(",", rng.choice([";", "\t", ",,"])) for line in lines]
    else:
        return mutate(text.encode(), rng)
    return ("\n".join(lines) + "\n").encode()


HA_MAP = """modbus:
  - name: hub
    type: serial
    sensors:
      - name: L1 voltage
        slave: 1
        address: 0
        input_type: input
        data_type: float32
        swap: word
        scale: 0.1
        unit_of_measurement: V
      - name: Energy
        slave: 1
        address: 10
        data_type: uint32
        scale: 0.001
        precision: 2
        offset: 3
      - name: Serial
        slave: 1
        address: 20
        data_type: string
        count: 4
      - name: Strings
        slave: 1
        address: 30
        data_type: int16
        slave_count: 2
"""
YAML_NASTY = ["", "~", ".inf", ".nan", "-1", "65536", "1e400", "[1, 2]", "{a: 1}", "!secret x", "!include o.yaml",
              "yes", "0x10", '"x"', "'", "[", "&anchor x", "*undefined", "- a", "|", ">", "2001-01-01", "custom",
              "word_byte", "input", "coil", "int", "float", "0o17", "1_000", "'" + "x" * 300 + "'", "@", "`"]


def mutate_yaml(text: str, rng: random.Random) -> bytes:
    lines = text.splitlines()
    k = rng.randrange(len(lines))
    kind = rng.randrange(7)
    if kind <= 1 and ":" in lines[k]:
        key, _, _ = lines[k].partition(":")
        lines[k] = f"{key}: {rng.choice(YAML_NASTY)}"
    elif kind == 2:
        del lines[k]
    elif kind == 3:
        lines.insert(k, lines[rng.randrange(len(lines))])
    elif kind == 4:  # indentation off by some
        lines[k] = " " * rng.choice([0, 1, 3, 12]) + lines[k].lstrip()
    elif kind == 5:
        lines.append(rng.choice(["x: " + "[" * 3000 + "]" * 3000, "\t- tab", "modbus: 5", "---", "...", "%YAML 9"]))
    else:
        return mutate(text.encode(), rng)
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("ext", ["csv", "yaml"])
def test_malformed_csv_and_yaml_maps(tmp_path, capsys, ext):
    rng = random.Random(f"{SEED}-map-{ext}")
    codes = []
    for case in range(2 * CASES):
        m = tmp_path / f"case{case}" / f"fuzz.{ext}"
        m.parent.mkdir()
        m.write_bytes(mutate_csv(CSV_MAP, rng) if ext == "csv" else mutate_yaml(HA_MAP, rng))
        base = ["--map-base", rng.choice(["0", "1", "modicon"])] if ext == "csv" and rng.random() < 0.3 else []
        code, _ = run(capsys, ["decode", *FRAMES, "--model-file", m, "--device", "1=fuzz", *base])
        codes.append(code)
    outcomes(codes)


# -- query ----------------------------------------------------------------------------------------
SQL_WORDS = ["SELECT", "FROM", "WHERE", "GROUP BY", "ORDER BY", "LIMIT", "UNION", "JOIN", "ON", "AND", "OR", "NOT",
             "NULL", "CASE", "WHEN", "THEN", "END", "AS", "DISTINCT", "count(*)", "min(", "max(", ")", "(", ",", ";",
             "'", '"', "--", "/*", "*/", "1::HUGEINT << 100", "'12:00+01'::TIMETZ", "'nan'::DOUBLE", "[1, 2]",
             "{'a': 1}", "frames", "points", "annotations", "captures", "nope", "\udcff", "1e308 * 10", "*", "=",
             "quantile_cont(latency_ms, 2)", "epoch_ns(time)", "INTERVAL 3 DAY", "'infinity'::DATE", "x'00'"]
SQL_HOSTILE = ["", " ", "-- nothing", ";", "/* only a comment */", ";;", "SELECT", "(" * 3000 + "1" + ")" * 3000,
               "SELECT " + "1+" * 2000 + "1", "SELECT '" + "x" * 100_000 + "'", "SELECT 1; SELECT 2",
               "SELECT 1::HUGEINT << 100, '12:00+01'::TIMETZ, 'nan'::DOUBLE, [1], {'a': 1}, x'00'"]


def mutate_sql(rng: random.Random) -> str:
    if rng.random() < 0.2:
        return rng.choice(SQL_HOSTILE)
    toks = rng.choice(list(PRESETS.values())).sql.split()
    for _ in range(rng.randint(1, 4)):
        i = rng.randrange(len(toks))
        kind = rng.randrange(3)
        if kind == 0:
            del toks[i]
        elif kind == 1:
            toks.insert(i, rng.choice(SQL_WORDS))
        else:
            toks[i] = rng.choice(SQL_WORDS)
    return " ".join(toks)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from sniffer.cli import main

    ds = tmp_path_factory.mktemp("fuzzds") / "fleet"
    assert main(["export", str(SIM / "errors.mcap"), "--to", "dataset", str(ds)]) == 0
    return ds


def test_malformed_queries(capsys, dataset):
    rng = random.Random(f"{SEED}-query")
    codes = []
    for _case in range(2 * CASES):
        fmt = rng.choice(["table", "csv", "json"])
        rows = rng.choice(["1", "5"])
        code, _ = run(capsys, ["query", dataset, mutate_sql(rng), "--format", fmt, "--max-rows", rows])
        codes.append(code)
    outcomes(codes)


# -- status files -----------------------------------------------------------------------------------
JSON_VALUES = ["x", "", 1.5, -1, 0, 10**30, -(10**400), float("nan"), float("inf"), [], {}, None, True, [1, [2]],
               {"a": {"b": {"c": 1}}}, "\ud800", "\n\t\x1b[31m", "y" * 10_000, [None] * 40]


def mutate_json(doc, rng: random.Random, depth: int = 0):
    """A copy of `doc` with one value somewhere replaced by a value of another kind, or a key removed."""
    if isinstance(doc, dict) and doc and depth < 3 and rng.random() < 0.6:
        k = rng.choice(list(doc))
        out = dict(doc)
        if rng.random() < 0.15:
            del out[k]
        else:
            out[k] = mutate_json(doc[k], rng, depth + 1)
        return out
    return rng.choice(JSON_VALUES)


def test_malformed_status_files(tmp_path, capsys):
    from sniffer.cli import main

    good = tmp_path / "good.json"
    assert main(["replay", str(WIZ), "--baud", "9600", "--status", str(good)]) == 0
    capsys.readouterr()
    seed = json.loads(good.read_text())
    rng = random.Random(f"{SEED}-status")
    codes = []
    for case in range(2 * CASES):
        p = tmp_path / f"status{case}.json"
        kind = rng.randrange(5)
        if kind == 0:
            p.write_bytes(mutate(good.read_bytes(), rng))
        elif kind == 1:
            p.write_text(rng.choice(["[" * 100_000 + "]" * 100_000, '{"a": ' * 50_000 + "1" + "}" * 50_000,
                                     "[]", "7", '"running"', "{}", "{" + '"frames": ' + "9" * 5000 + "}"]))
        else:
            p.write_text(json.dumps(mutate_json(seed, rng)))
        code, _ = run(capsys, ["status", p, *(["--json"] if rng.random() < 0.3 else [])], codes=(0, 1, 2),
                      warnings=1)
        codes.append(code)
    assert 2 in codes and (0 in codes or 1 in codes), sorted(set(codes))


# -- --trigger, --on-trigger, --status ---------------------------------------------------------------
FILTERS = ["crc", "u:1 fc:3", "lat>20ms", "rate(crc) > 5/min", '"Output frequency" > 50', "reg:2520H..2525H",
           "not (exc or timeout)", "t:1s..2s", "link:a", "model:a510", "holding[300] = 5", "err & !noise",
           "fc:0x10,3 role:req", "u:1,2..5", "lat:..5ms", "rate(timeout u:3) >= 3/10s", "12-00", "~"]
FILTER_CHARS = '()"\':<>=!~&|,.[] -0123456789abcdefHuxz/'


def mutate_filter(rng: random.Random) -> str:
    f = rng.choice(FILTERS)
    kind = rng.randrange(6)
    if kind == 0:
        i = rng.randrange(len(f) + 1)
        return f[:i] + "".join(rng.choice(FILTER_CHARS) for _ in range(rng.randint(1, 4))) + f[i:]
    if kind == 1:
        i = rng.randrange(len(f))
        return f[:i] + f[i + rng.randint(1, 3):]
    if kind == 2:
        n = rng.choice([2, 50, 99, 101, 500, 5000])
        return rng.choice(["(" * n + f + ")" * n, "not " * n + f, "!" * n + f])
    if kind == 3:
        op = f" {rng.choice(['and', 'or', '|', '&&', ''])} "
        return op.join(rng.choice(FILTERS) for _ in range(rng.randint(2, 300)))
    if kind == 4:
        return rng.randbytes(rng.randint(1, 40)).decode("latin-1")
    return f


ON_TRIGGER = ["true", "false", "exit 3", "exit 255", "nonexistent-command-xyz", 'echo "$SNIFFER_WINDOW"',
              "cat /dev/null", "sleep 0.2", "'", '"', "echo x >&2", "printf 'line\\n%.0s' 1 2 3 4 5 6 7 8 9 10",
              "kill -9 $$", "", " ", "ls -l -- \"$SNIFFER_WINDOW\" >/dev/null"]
TIMEOUTS = ["1s", "0.5s", "2", "0", "-1", "x", "1e9s", "10ms", "", "5 min"]


def test_malformed_triggers_and_on_trigger_commands(tmp_path, capsys):
    rng = random.Random(f"{SEED}-trigger")
    codes = []
    for case in range(2 * CASES):
        windows = tmp_path / f"w{case}"
        windows.mkdir()
        args = ["replay", WIZ, "--baud", "9600", "--windows", windows, "--pre", rng.choice(["1s", "0", "5m"])]
        if rng.random() < 0.6:
            args += ["--trigger", mutate_filter(rng)]
        else:  # a trigger that fires, and a command for each window
            args += ["--trigger", rng.choice(["u:1", "fc:3", "crc or exc"]), "--on-trigger", rng.choice(ON_TRIGGER)]
            if rng.random() < 0.5:
                args += ["--on-trigger-timeout", rng.choice(TIMEOUTS)]
        code, _ = run(capsys, args)
        codes.append(code)
    outcomes(codes)


def test_hostile_status_paths(tmp_path, capsys):
    """--status where it cannot be written: a folder, a missing folder, through a file, a long or empty name."""
    (tmp_path / "afile").write_text("x")
    paths = [tmp_path, tmp_path / "missing" / "s.json", tmp_path / "afile" / "s.json", tmp_path / ("x" * 300),
             "", tmp_path / "s\nnewline.json", tmp_path / "ok.json", tmp_path / "afile"]
    codes = []
    for p in paths:
        code, _ = run(capsys, ["replay", WIZ, "--baud", "9600", "--status", p], warnings=3)
        codes.append(code)
    assert 0 in codes


# -- ingest ---------------------------------------------------------------------------------------
def test_malformed_ingests(tmp_path, capsys):
    """A folder of mutated and cut captures into a dataset whose dataset.json, manifest entries and staging
    folder are mutated between runs; then a query over it."""
    from sniffer.cli import main

    rng = random.Random(f"{SEED}-ingest")
    good = [(SIM / name).read_bytes() for name in ("errors.mcap", "a510.mcap")]
    codes = []
    for case in range(CASES // 2):
        folder, ds = tmp_path / f"in{case}", tmp_path / f"ds{case}"
        folder.mkdir()
        for i in range(2):
            data = rng.choice(good)
            (folder / f"c{i}.mcap").write_bytes(mutate(data, rng) if rng.random() < 0.7 else data)
        assert main(["ingest", str(folder), "--to", str(ds)]) in (0, 2)  # a dataset to mutate
        capsys.readouterr()
        targets = [*sorted((ds / "_manifest").glob("*.json")), ds / "dataset.json"]
        for _ in range(rng.randint(1, 3)):
            t = rng.choice(targets)
            if rng.random() < 0.5:
                t.write_bytes(mutate(t.read_bytes(), rng))
            else:
                try:
                    doc = json.loads(t.read_bytes())
                except ValueError:
                    doc = {}
                t.write_text(json.dumps(mutate_json(doc, rng)))
        if rng.random() < 0.3:  # a killed run's leftovers
            junk = ds / "_staging" / rng.choice(["x.1", "y-0123.99999999", "z", ".lock"])
            junk.mkdir(parents=True, exist_ok=True)
        shutil.copy(folder / "c0.mcap", folder / "again.mcap")
        (folder / "c1.mcap").write_bytes(mutate((folder / "c1.mcap").read_bytes(), rng))  # changed since
        code, lines = run_ingest(capsys, folder, ds)
        codes.append(code)
        run(capsys, ["query", ds, "SELECT count(*) FROM frames", "--format", "csv"])
    assert 2 in codes


def run_ingest(capsys, folder, ds) -> tuple[int, list[str]]:
    """ingest: exit 0, 1 or 2, every line the sniffer's, an error line per capture not taken in."""
    from fuzzing import bounded

    from sniffer.cli import main

    with bounded(what=f"ingest {folder}"):
        code = main(["ingest", str(folder), "--to", str(ds)])
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in out + err and code in (0, 1, 2), (code, lines[-5:])
    assert all(line.startswith("sniffer: ") for line in lines), lines
    if code == 2 and not any("taken in (" in line for line in lines):  # refused before any capture
        assert len(lines) == 1 and lines[0].startswith("sniffer: error: "), lines
    return code, lines
