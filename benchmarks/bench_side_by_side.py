"""Ours against tshark and pymodbus on the same capture, in one run: whole processes, start-up included.

    .venv/bin/python benchmarks/bench_side_by_side.py [--frames 50000] [--links-frames 20000] [--keep DIR]
                                                      [--no-links] [--no-tui]

1. The capture (not timed): `sniffer simulate --scenario stress` for about --frames frames and the same
   frames as a pcap (bench_jobs.make_capture; `--keep DIR` keeps both for the next run with the same
   --frames).
2. Peers, each a fresh process under /usr/bin/time (bench_jobs.timed): `tshark -n -r PCAP` with the mbrtu
   dissector on DLT 147 (formats.pcap TSHARK_ARGS: a summary line a packet), the same with `-V` (every
   field), and pymodbus' RTU framer on the pcap's packets (this script's `--pymodbus-child`: the packets
   read with struct, each through pymodbus' response decoder, then its request decoder if that one
   refuses it; the pcap does not say a packet's direction).  pymodbus is optional (`pip install -e
   '.[bench]'`): without it the row says so.
3. Ours, each a fresh process with `--jobs 1` and with no --jobs (the default): `replay --quiet`, `replay`
   (text), `export --to csv`, `export --to parquet`, `check` (against a golden written first, not timed),
   `diagnose`, `report`.  Output goes to /dev/null or a temp dir; every process's stdout alike.
4. With links (unless --no-links): a capture of two links read by USB adapters (bench_jobs_default's
   links_capture, about --links-frames frames): `replay`, `diagnose` and `report` at --jobs 1 and the default.
5. The TUI's open time (unless --no-tui): `sniffer replay CAP --tui` on a pty until the status bar says
   [ended] (tui_terminal.replay, the loading scenario of bench_tui.py, with two keys pressed while it loads).

Printed: a row per run with wall seconds, frames/s, the ratio to tshark's summary rate, CPU seconds (the
workers included), peak RSS of the largest process (/usr/bin/time %M) and the load average before it, with
the target of the issue that asked for this table beside ours, and frames per CPU second.  Nothing is
asserted: on a loaded machine the wall columns mean little (the CPU columns hold better).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import shutil
import struct
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_jobs import SNIFFER, make_capture, sh, timed  # noqa: E402

TSHARK_FPS = "tshark"  # a target given as tshark's summary rate in the same run
# name, argv after `sniffer`, target frames/s (per core, from the issue)
OURS = [
    ("replay --quiet", ["replay", "{cap}", "--quiet"], TSHARK_FPS),
    ("replay (text)", ["replay", "{cap}"], 100_000),
    ("export csv", ["export", "{cap}", "--to", "csv", "--out", "{o}/x-{j}.csv"], 100_000),
    ("export parquet", ["export", "{cap}", "--to", "parquet", "--out", "{o}/x-{j}.parquet"], 100_000),
    ("check", ["check", "{cap}", "--golden", "{o}/golden.txt"], TSHARK_FPS),
    ("diagnose", ["diagnose", "{cap}"], 50_000),
    ("report", ["report", "{cap}", "--out", "{o}/r-{j}.html"], 50_000),
]
LINK_ROWS = ("replay (text)", "diagnose", "report")
TUI_TARGET_FPS = 1_000_000 / 15  # the last frame of a million-frame capture on the list within 15 s


# ------------------------------------------------------------------ the pymodbus peer (a child process)
def pymodbus_child(pcap: str) -> None:
    """Every packet of a classic pcap through pymodbus' RTU framer; prints packets and decoded counts."""
    import logging

    from pymodbus.exceptions import ModbusIOException
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL + 1)  # no "Unable to decode" line a frame
    response = FramerRTU(DecodePDU(is_server=False)).handleFrame
    request = FramerRTU(DecodePDU(is_server=True)).handleFrame
    data = Path(pcap).read_bytes()
    end = "<" if data[:4] in (b"\x4d\x3c\xb2\xa1", b"\xd4\xc3\xb2\xa1") else ">"
    pos, packets, decoded = 24, 0, 0
    while pos + 16 <= len(data):
        incl = struct.unpack_from(end + "I", data, pos + 8)[0]
        raw = data[pos + 16:pos + 16 + incl]
        pos += 16 + incl
        packets += 1
        for handle in (response, request):
            try:
                if handle(raw, 0, 0)[1] is not None:
                    decoded += 1
                    break
            except ModbusIOException:
                pass
    print(f"{packets} {decoded}")


# ------------------------------------------------------------------ runs
def run(label: str, argv: list[str], frames: int, target, group: str, out: Path) -> dict:
    r = timed(argv, None)
    r.update(label=label, frames=frames, target=target, group=group)
    ok = "" if r["rc"] in (0, 1) else f"  exit {r['rc']}: {r['stderr'].strip().splitlines()[-1:]}"
    print(f"  {label:34s} {r['wall']:6.1f} s  load {r['load']:.1f}{ok}", file=sys.stderr, flush=True)
    return r


def peers(pcap: Path, n: int, out: Path) -> tuple[list[dict], list[str]]:
    from sniffer.formats.pcap.format import TSHARK_ARGS

    rows, notes = [], []
    exe = shutil.which("tshark")
    if exe:
        base = [exe, "-n", "-r", str(pcap), *TSHARK_ARGS]
        rows.append(run("tshark -r (summary line, mbrtu)", base, n, None, "peer", out))
        rows.append(run("tshark -r -V (every field)", [*base, "-V"], n, None, "peer", out))
    else:
        notes.append("tshark: not installed (apt-get install tshark)")
    if importlib.util.find_spec("pymodbus"):
        argv = [sys.executable, __file__, "--pymodbus-child", str(pcap)]
        rows.append(run("pymodbus FramerRTU (per packet)", argv, n, None, "peer", out))
        got = sh(argv).stdout.split()
        if len(got) == 2:
            notes.append(f"pymodbus: {int(got[1]):,} of {int(got[0]):,} packets decoded (response decoder, then "
                         "request decoder: the pcap does not say a packet's direction)")
    else:
        notes.append("pymodbus: not installed (pip install -e '.[bench]'), its row left out")
    return rows, notes


def ours(cap: Path, n: int, out: Path, names, group: str) -> list[dict]:
    rows = []
    for name, argv, target in OURS:
        if name not in names:
            continue
        if name == "check":  # its golden first, not timed
            sh([*SNIFFER, "check", str(cap), "--golden", str(out / "golden.txt"), "--update-golden", "--jobs", "1"])
        for j in ("1", None):
            a = [x.format(cap=cap, o=out, j=j or "d") for x in argv]
            label = f"{'sniffer ' + name:26s} {'--jobs 1' if j else 'default'}"
            rows.append(run(label, [*SNIFFER, *a, *(["--jobs", j] if j else [])], n, target, group, out))
    return rows


def tui_open(cap: Path, n: int) -> tuple[dict | None, str]:
    if importlib.util.find_spec("pyte") is None:
        return None, "TUI: pyte not installed (pip install -e '.[bench]'), its row left out"
    import tui_terminal

    load = os.getloadavg()[0]
    _loading, _idle, load_s = tui_terminal.replay(cap, n_keys=2, max_runs=1)
    if not load_s:
        return None, "TUI: the replay never said [ended]"
    return {"label": "sniffer replay --tui (to [ended])", "wall": load_s[0], "cpu": None, "rss_mb": None,
            "rc": 0, "load": load, "frames": n, "target": TUI_TARGET_FPS, "group": "tui"}, ""


# ------------------------------------------------------------------ the table
def table(rows: list[dict], tshark_fps: float | None) -> None:
    head = ["", "frames", "wall s", "frames/s", "vs tshark", "target frames/s", "met", "CPU s", "frames/CPU s",
            "peak RSS MB", "load"]
    lines = [head]
    group = None
    for r in rows:
        if r["group"] != group and group is not None:
            lines.append([])
        group = r["group"]
        fps = r["frames"] / r["wall"]
        target = tshark_fps if r["target"] == TSHARK_FPS else r["target"]
        tgt = "-" if target is None else f"{target:,.0f}" + (" (tshark)" if r["target"] == TSHARK_FPS else "")
        met = "-" if target is None else "yes" if fps >= target else "no"
        bad = r["rc"] not in (0, 1)
        lines.append([r["label"], f"{r['frames']:,}", f"{r['wall']:.2f}", f"{fps:,.0f}" + (" FAILED" if bad else ""),
                      f"{fps / tshark_fps:.2f}" if tshark_fps and r["group"] != "links" else "-", tgt, met,
                      "-" if r["cpu"] is None else f"{r['cpu']:.1f}",
                      f"{r['frames'] / r['cpu']:,.0f}" if r["cpu"] else "-",
                      "-" if r["rss_mb"] is None else f"{r['rss_mb']:.0f}", f"{r['load']:.1f}"])
    widths = [max(len(x[i]) for x in lines if x) for i in range(len(head))]
    for x in lines:
        if not x:
            print()
            continue
        print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(x, widths))))


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--pymodbus-child":
        pymodbus_child(sys.argv[2])
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=50_000, help="frames of the stress capture (default 50000)")
    ap.add_argument("--links-frames", type=int, default=20_000, help="frames of the two-link capture")
    ap.add_argument("--keep", metavar="DIR", help="keep the captures here (and reuse them)")
    ap.add_argument("--no-links", action="store_true", help="leave out the two-link capture")
    ap.add_argument("--no-tui", action="store_true", help="leave out the TUI's open time")
    args = ap.parse_args()
    from sniffer.parallel.options import cores

    folder = Path(args.keep or tempfile.mkdtemp(prefix="bench_side_"))
    folder.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkdtemp(prefix="bench_side_out_"))
    notes: list[str] = []
    try:
        cap, pcap, n = make_capture(folder, args.frames)
        print(f"stress capture: {n:,} frames", file=sys.stderr)
        rows, notes = peers(pcap, n, out)
        rows += ours(cap, n, out, [name for name, _a, _t in OURS], "ours")
        if not args.no_links:
            from bench_jobs_default import links_capture

            from bench_commands import count_mcap_frames

            lcap = links_capture(folder, args.links_frames)[0]
            ln = count_mcap_frames(lcap)
            for r in ours(lcap, ln, out, LINK_ROWS, "links"):
                r["label"] = r["label"].replace("sniffer", "2 links:", 1)
                rows.append(r)
        if not args.no_tui:
            tui, note = tui_open(cap, n)
            rows += [tui] if tui else []
            notes += [note] if note else []
    finally:
        shutil.rmtree(out, ignore_errors=True)
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)
    ts = next((r for r in rows if r["label"].startswith("tshark -r (")), None)
    tshark_fps = ts["frames"] / ts["wall"] if ts and ts["rc"] == 0 else None
    print()
    table(rows, tshark_fps)
    print()
    for note in notes:
        print(note)
    print("vs tshark: against tshark's summary rate on the stress capture (left out for the two-link capture, "
          "another capture)")
    print("targets per core (one process); the TUI's: a million frames on the list within 15 s. "
          "default = no --jobs flag (sniffer.parallel.options.default_jobs)")
    print(f"{os.cpu_count()} CPUs, {cores()} usable ({platform.processor() or platform.machine()}); "
          f"Python {platform.python_version()}; load average now {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    from sniffer.hot import describe

    print(f"ours: {describe()} (SNIFFER_PURE=1 for the pure-Python path; docs/install.md)")


if __name__ == "__main__":
    main()
