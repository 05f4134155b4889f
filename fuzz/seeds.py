"""Write the seed corpus (fuzz/corpus/TARGET/seed-*) from the repository's own inputs: `python fuzz/seeds.py`.

Small on purpose (a few hundred bytes to a few kB each): the fuzzer mutates them thousands of times a
minute.  Crash inputs found later are kept beside them under their own names (crash-*), never rewritten here.
"""

from __future__ import annotations

import io
import json
import struct
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from targets import CORPUS, ROOT, WIZ  # noqa: E402


def _sniffer(*argv) -> None:
    from sniffer.cli import main

    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        rc = main([str(a) for a in argv])
    assert rc in (0, 1), (argv, rc)


def seeds() -> dict[str, dict[str, bytes]]:
    tmp = Path(tempfile.mkdtemp(prefix="fuzz-seeds-"))
    rows = WIZ.read_text().splitlines()
    small = tmp / "wiz.csv"
    small.write_text("\n".join(rows[:41]) + "\n")  # the header and 40 bytes: a few exchanges
    out: dict[str, dict[str, bytes]] = {"bytecsv": {"wiz": small.read_bytes()}}
    for kind in ("mcap", "pcap", "pcapng"):
        _sniffer("export", small, "--baud", "9600", "--to", "pcap" if kind == "pcapng" else kind,
                 "--out", tmp / f"wiz.{kind}")
        out[kind] = {"wiz": (tmp / f"wiz.{kind}").read_bytes()}
    out["saleae"] = {"wiz": ("name,type,start_time,duration,data\n" + "".join(
        f'"Async Serial {ch}","data",{t},0.000937,0x{b.upper()}\n'
        for t, ch, b, _f in (r.split(",") for r in rows[1:41]))).encode()}
    sr = ROOT / "captures" / "refcaptures" / "sigrok" / "brainchild-io-16do.sr"
    out["sigrok"] = {"brainchild": sr.read_bytes()} if sr.stat().st_size < 64_000 else {}
    out["bus"] = {"serial": b'[serial]\nbaud = 9600\nparity = "N"\nstopbits = 1\nprotocol = "modbus-rtu"\n\n'
                            b'[units]\n1 = "generic"\n2 = "a510"\n\n[timeouts_ms]\n1 = 250\n',
                  "units": b'[serial]\nbaud = 9600\n[units]\n1 = "a510"\n[timeouts_ms]\n1 = 100\n'}
    sys.path.insert(0, str(ROOT / "tests"))
    from test_input_fuzz import MAP
    from test_surface_fuzz import CSV_MAP, HA_MAP

    out["map_toml"] = {"fuzz": MAP.encode()}
    # the test's map ends with a row it means to be refused (an address 0x14H): a readable one here
    out["map_csv"] = {"fuzz": CSV_MAP.replace("0x14H,Mode,u16,,,RW", "0x16,Mode,u16,,,R").encode()}
    out["map_yaml"] = {"fuzz": HA_MAP.encode()}
    _sniffer("check", small, "--baud", "9600", "--golden", tmp / "golden.txt", "--update-golden")
    out["golden"] = {"wiz": (tmp / "golden.txt").read_bytes()}
    out["params"] = {"saved": b"unit,register,value\n2,An-01,30.0\n1,Cn-02,60\n"}
    _sniffer("replay", small, "--baud", "9600", "--status", tmp / "status.json")
    status = json.loads((tmp / "status.json").read_text())
    out["status"] = {"replay": json.dumps(status, indent=1).encode()}
    out["framers"] = {  # the first byte: the reads' size and silences (targets.run_framers)
        "rtu": bytes([0x47]) + bytes.fromhex("010300000002C40B01030400010002" "2A32"),
        "ascii": bytes([0x8F]) + b":010300000002FA\r\n:0103040001000275\r\n",
        "noise": bytes([0x00]) + bytes(range(0, 256, 7)),
    }
    raw = b'{"kind":"chunk","t_ns":12,"data":"010300000002c40b","byte_dt_ns":null,"flags":[],"channel":""}'
    message = struct.pack("<BQHIQQ", 5, 22 + len(raw), 1, 0, 5, 5) + raw
    out["hot"] = {  # the first byte as for framers; the rest as RTU bytes, a /raw message, a chunk's records
        "rtu": bytes([0x47]) + bytes.fromhex("010300000002C40B01030400010002" "2A32" "0110000A0002040001000AD3A1"),
        "raw": bytes([0x00]) + raw,
        "chunk": bytes([0x00]) + message * 2,
    }
    out["filter"] = {f"f{i}": f.encode() for i, f in enumerate([
        "crc", "u:1 fc:3", "lat>20ms", "rate(crc) > 5/min", '"Output frequency" > 50', "reg:2520H..2525H",
        "not (exc or timeout)", "t:1s..2s", "link:a", "model:a510", "holding[300] = 5", "err & !noise",
        "fc:0x10,3 role:req", "u:1,2..5", "lat:..5ms", "rate(timeout u:3) >= 3/10s", "12-00"])}
    return out


def write() -> None:
    for target, files in seeds().items():
        folder = CORPUS / target
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("seed-*"):
            old.unlink()
        for name, data in files.items():
            (folder / f"seed-{name}").write_bytes(data)
        print(f"{target}: {len(files)} seeds, {sum(map(len, files.values()))} bytes")


if __name__ == "__main__":
    write()
