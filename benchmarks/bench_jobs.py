"""--jobs 1 against --jobs N on a 1,000,000-frame capture, and tshark on the same frames as a pcap, in one run.

    .venv/bin/python benchmarks/bench_jobs.py [--frames 1000000] [--jobs N] [--keep DIR] [--only replay,check]

1. The capture (not timed): `sniffer simulate --scenario stress` for enough bus time to give
   at least --frames frames (125-register reads, errors, FTDI-like reads; its rate measured on
   20 s of the same scenario, plus 2 %), and its frames as a pcap (`sniffer export --to pcap`).
   `--keep DIR` keeps both there for the next run with the same --frames.
2. Each command runs twice in a fresh process, with --jobs 1 and with --jobs N (default: the
   cores this process may use), under /usr/bin/time: wall seconds, CPU seconds (user + system,
   the worker processes included), and the peak RSS of the largest process.  The two outputs
   are compared byte for byte (the report's page but for the time it was written), and the
   row says whether they are the same.
3. tshark -r the pcap with the mbrtu dissector (bench_commands.tshark_peer), in the same run.

Printed: per command the seconds and frames/s of each, the speed-up and the speed-up per core
(the aim: at least 0.8), ours against tshark's frames/s, the load average before each run, and
the machine.  Nothing is asserted: tests never assert wall-clock times.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
SNIFFER = [sys.executable, "-m", "sniffer"]


def _compile_sources() -> None:
    """Bytecode for the checkout, as a field install (pip, pipx) has: with PYTHONDONTWRITEBYTECODE set (these
    machines) an editable install would compile every module again in each timed process (about 0.2 s)."""
    import compileall

    for package in ("sniffer", "decoders"):
        compileall.compile_dir(str(HERE.parent / package), quiet=2)


_compile_sources()
STRESS_FPS_PROBE_S = 20

# name, argv after the capture, outputs (compared between the two runs; {j} is the run's job count)
ROWS = [
    ("replay", ["replay", "{cap}"], ["replay-{j}.txt"]),  # stdout to the file
    ("replay jsonl", ["replay", "{cap}", "--format", "jsonl"], ["replay-{j}.jsonl"]),
    ("export pcap", ["export", "{cap}", "--to", "pcap", "--out", "{o}/x-{j}.pcap"], ["x-{j}.pcap"]),
    ("export csv", ["export", "{cap}", "--to", "csv", "--out", "{o}/x-{j}.csv"], ["x-{j}.csv", "x-{j}.points.csv"]),
    ("export parquet", ["export", "{cap}", "--to", "parquet", "--out", "{o}/x-{j}.parquet"],
     ["x-{j}.parquet", "x-{j}.points.parquet"]),
    ("export mcap", ["export", "{cap}", "--to", "mcap", "--out", "{o}/x-{j}.mcap"], ["x-{j}.mcap"]),
    ("check", ["check", "{cap}", "--golden", "{o}/golden.txt"], []),
    ("report", ["report", "{cap}", "--out", "{o}/r-{j}.html"], ["r-{j}.html"]),
    ("diagnose", ["diagnose", "{cap}", "--format", "json"], ["diagnose-{j}.json"]),  # stdout to the file
]


def sh(argv, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(argv, capture_output=True, text=True, **kw)


def make_capture(folder: Path, frames: int) -> tuple[Path, Path, int]:
    """(capture, pcap, frames in it), made once per --frames in `folder`."""
    cap, pcap = folder / f"stress-{frames}.mcap", folder / f"stress-{frames}.pcap"
    meta = folder / f"stress-{frames}.json"
    if cap.exists() and pcap.exists() and meta.exists():
        return cap, pcap, json.loads(meta.read_text())["frames"]
    probe = folder / "probe.mcap"
    r = sh([*SNIFFER, "simulate", "--scenario", "stress", "--duration", str(STRESS_FPS_PROBE_S), "--out", str(probe)])
    got = int(re.search(r"wrote (\d+) frames", r.stderr).group(1))
    probe.unlink()
    seconds = math.ceil(frames / (got / STRESS_FPS_PROBE_S) * 1.02)
    print(f"simulating {seconds} s of the stress scenario ({got / STRESS_FPS_PROBE_S:.0f} frames/s) ...",
          file=sys.stderr)
    r = sh([*SNIFFER, "simulate", "--scenario", "stress", "--duration", str(seconds), "--out", str(cap)])
    if r.returncode:
        sys.exit(f"simulate failed: {r.stderr}")
    n = int(re.search(r"wrote (\d+) frames", r.stderr).group(1))
    r = sh([*SNIFFER, "export", str(cap), "--to", "pcap", "--out", str(pcap)])
    if r.returncode:
        sys.exit(f"export --to pcap failed: {r.stderr}")
    meta.write_text(json.dumps({"frames": n, "seconds": seconds}))
    return cap, pcap, n


def timed(argv: list[str], stdout_path: Path | None) -> dict:
    """argv in a fresh process under /usr/bin/time: wall, cpu (children included), peak RSS (MB), exit code."""
    usage = Path(tempfile.mktemp(suffix=".time"))
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    with open(stdout_path or os.devnull, "wb") as out:
        p = subprocess.run(["/usr/bin/time", "-o", str(usage), "-f", "%e %U %S %M", *argv], stdout=out,
                           stderr=subprocess.PIPE)
    wall = time.perf_counter() - t0
    _e, user, system, kib = usage.read_text().split()[-4:]
    usage.unlink()
    return {"wall": wall, "cpu": float(user) + float(system), "rss_mb": int(kib) * 1024 / 1e6, "rc": p.returncode,
            "load": load, "stderr": p.stderr.decode(errors="replace")[-300:]}


def same(out: Path, names: list[str], jobs: int) -> bool | None:
    if not names:
        return None
    for name in names:
        a, b = out / name.format(j=1), out / name.format(j=jobs)
        if name.endswith(".html"):
            strip = re.compile(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")
            if strip.sub(b"", a.read_bytes()) != strip.sub(b"", b.read_bytes()):
                return False
        elif not filecmp.cmp(a, b, shallow=False):
            return False
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--jobs", type=int, default=None, help="N (default: the cores this process may use)")
    ap.add_argument("--keep", metavar="DIR", help="keep the capture and pcap here (and reuse them)")
    ap.add_argument("--only", help="comma-separated command names (e.g. 'replay,export pcap')")
    args = ap.parse_args()
    from sniffer.parallel.options import cores

    jobs = args.jobs or cores()
    folder = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_jobs_"))
    folder.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkdtemp(prefix="bench_jobs_out_"))
    try:
        cap, pcap, n = make_capture(folder, args.frames)
        only = {x.strip() for x in args.only.split(",")} if args.only else None
        rows = []
        for name, argv, outputs in ROWS:
            if only and name not in only:
                continue
            if name == "check":  # its golden first (not timed)
                sh([*SNIFFER, "check", str(cap), "--golden", str(out / "golden.txt"), "--update-golden"])
            res = {}
            for j in (1, jobs):
                a = [x.format(cap=cap, o=out, j=j) for x in argv]
                stdout = out / outputs[0].format(j=j) if name.startswith(("replay", "diagnose")) else None
                res[j] = timed([*SNIFFER, *a, "--jobs", str(j)], stdout)
            rows.append((name, res, same(out, outputs, jobs)))
            r1, rn = res[1], res[jobs]
            print(f"{name:16s} 1: {r1['wall']:7.1f} s  {jobs}: {rn['wall']:7.1f} s  x{r1['wall'] / rn['wall']:.2f}  "
                  f"load {r1['load']:.1f}/{rn['load']:.1f}", file=sys.stderr)
        from bench_commands import tshark_peer

        ts = tshark_peer(pcap, out)
        report(rows, ts, n, jobs)
    finally:
        shutil.rmtree(out, ignore_errors=True)
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)


def report(rows, ts: dict, n: int, jobs: int) -> None:
    import platform

    fps_ts = ts.get("packets", 0) / ts["seconds"] if "seconds" in ts else None
    head = (f"{'command':16s} {'--jobs 1 s':>10s} {'frames/s':>9s} {f'--jobs {jobs} s':>10s} {'frames/s':>9s} "
            f"{'speed-up':>8s} {'per core':>8s} {'CPU s 1/N':>11s} {'peak MB 1/N':>12s} {'same':>5s} "
            f"{'vs tshark (1/N)':>15s} {'load 1/N':>9s}")
    print(head)
    print("-" * len(head))
    for name, res, ok in rows:
        r1, rn = res[1], res[jobs]
        f1, fn = n / r1["wall"], n / rn["wall"]
        vs = f"{f1 / fps_ts:.2f}/{fn / fps_ts:.2f}" if fps_ts else "-"
        fails = "" if r1["rc"] == rn["rc"] and r1["rc"] in (0, 1) else f" rc {r1['rc']}/{rn['rc']}"
        mark = "-" if ok is None else "yes" if ok else "NO"
        print(f"{name:16s} {r1['wall']:10.1f} {f1 / 1e3:8.1f}k {rn['wall']:10.1f} {fn / 1e3:8.1f}k "
              f"{r1['wall'] / rn['wall']:8.2f} {r1['wall'] / rn['wall'] / jobs:8.2f} "
              f"{r1['cpu']:5.1f}/{rn['cpu']:5.1f} {r1['rss_mb']:5.0f}/{rn['rss_mb']:5.0f} "
              f"{mark:>5s} {vs:>15s} {r1['load']:4.1f}/{rn['load']:4.1f}{fails}")
    if "error" in ts:
        print(f"tshark: {ts['error']}")
    else:
        print(f"tshark -r PCAP (mbrtu on DLT 147, a summary line per packet): {ts['seconds']:.1f} s, "
              f"{fps_ts / 1e3:.1f}k frames/s, {ts['cpu']:.1f} CPU s, {ts['rss_mb']:.0f} MB peak, "
              f"{ts['packets']:,} packets; load {ts['load']:.1f}")
    print(f"{n:,} frames; --jobs {jobs} on {os.cpu_count()} CPUs ({platform.processor() or platform.machine()}); "
          f"Python {platform.python_version()}; load average now {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
