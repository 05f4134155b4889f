"""Does the default --jobs only help?  Every command at --jobs 1, --jobs N and the default, per capture size and links.

    .venv/bin/python benchmarks/bench_jobs_default.py [--frames 25000,100000,300000] [--links] [--keep DIR]
                                                      [--only replay,diagnose]

For each capture (the stress scenario at each --frames, made once with bench_jobs.make_capture; with
--links also a capture of two simulated links read by USB adapters) each command of bench_jobs.ROWS
runs in a fresh process three times: --jobs 1, --jobs N (N = the cores) and without --jobs (the
default, sniffer.parallel.options.default_jobs).  Measured, start-up included: wall seconds, CPU
seconds (the workers included), the peak RSS of the largest process and the peak of the sum of the
process tree's RSS (polled every 20 ms from /proc).  Printed: a row per command and capture, with
which the default chose and whether it was the faster of the two (within 5 %), and whether its
peak stays under 100 MB.  Nothing is asserted: tests never assert wall-clock times, and on a loaded
machine the wall columns mean little (the CPU columns hold better).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from bench_jobs import ROWS, SNIFFER, make_capture, sh  # noqa: E402


def _tree(pid: int) -> list[int]:
    out = [pid]
    try:
        kids = open(f"/proc/{pid}/task/{pid}/children").read().split()
    except OSError:
        return out
    for k in kids:
        out += _tree(int(k))
    return out


def _kb(pid: int, key: str) -> int:
    try:
        for line in open(f"/proc/{pid}/status"):
            if line.startswith(key):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def measured(argv: list[str]) -> dict:
    """argv in a fresh process: wall, CPU (children included), peak RSS of the largest process, peak total RSS."""
    t0 = time.perf_counter()
    before = os.times()
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    largest = total = 0
    while p.poll() is None:
        s = 0
        for q in _tree(p.pid):
            largest = max(largest, _kb(q, "VmHWM"))
            s += _kb(q, "VmRSS")
        total = max(total, s)
        time.sleep(0.02)
    after = os.times()
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return {"wall": time.perf_counter() - t0, "cpu": cpu, "largest": largest / 1024, "total": total / 1024,
            "rc": p.returncode}


def _default(argv: list[str], cap: Path, out: Path) -> int:
    """What the default --jobs chose for this command (sniffer.parallel.options.default_jobs)."""
    from sniffer.capture.settings import CaptureSpec
    from sniffer.cli import build_parser
    from sniffer.parallel.options import default_jobs

    args = build_parser().parse_args([x.format(cap=cap, o=out, j="d") for x in argv])
    return default_jobs(CaptureSpec.from_args(args), args)


def links_capture(folder: Path, frames: int) -> tuple[Path, int]:
    """Two links (errors and tds-v8) read by USB adapters, about `frames` frames."""
    cap = folder / f"links-{frames}.mcap"
    if not cap.exists():
        code = f"""
import sys
sys.path.insert(0, {str(HERE.parent / 'tests')!r})
from test_parallel_links import _write_links
_write_links({str(cap)!r}, ("errors", "tds-v8"), {frames / 100:.0f})
"""
        r = sh([sys.executable, "-c", code])
        if r.returncode:
            sys.exit(r.stderr)
    from bench_commands import count_mcap_frames

    return cap, count_mcap_frames(cap)  # (replay --quiet prints no line a frame: counting its output gave 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", default="25000,100000,300000")
    ap.add_argument("--links", action="store_true", help="also a capture of two links")
    ap.add_argument("--keep", metavar="DIR")
    ap.add_argument("--only", help="comma-separated command names (bench_jobs.ROWS)")
    args = ap.parse_args()
    from sniffer.parallel.options import cores

    jobs = cores()
    folder = Path(args.keep or tempfile.mkdtemp(prefix="bench_jobs_default_"))
    folder.mkdir(parents=True, exist_ok=True)
    out = Path(tempfile.mkdtemp(prefix="bench_jobs_default_out_"))
    caps = []
    for n in (int(x) for x in args.frames.split(",")):
        cap, _pcap, got = make_capture(folder, n)
        caps.append((f"stress {got // 1000}k", cap, got))
    if args.links:
        cap = links_capture(folder, 20_000)[0]
        caps.append(("2 links", cap, 20_000))
    only = {x.strip() for x in args.only.split(",")} if args.only else None
    head = (f"{'command':15s} {'capture':12s} {'j1 s':>6s} {f'j{jobs} s':>6s} {'dflt s':>6s} {'dflt':>4s} "
            f"{'best?':>5s} {'CPU 1/N/d':>14s} {'largest MB 1/N/d':>16s} {'total MB d':>10s} {'<100':>4s}")
    print(head)
    print("-" * len(head))
    for label, cap, _n in caps:
        for name, argv, _outputs in ROWS:
            if only and name not in only:
                continue
            if name == "check":
                sh([*SNIFFER, "check", str(cap), "--golden", str(out / "golden.txt"), "--update-golden", "--jobs", "1"])
            res = {}
            for j in ("1", str(jobs), None):
                a = [x.format(cap=cap, o=out, j=j or "d") for x in argv]
                res[j] = measured([*SNIFFER, *a, *(["--jobs", j] if j else [])])
            r1, rn, rd = res["1"], res[str(jobs)], res[None]
            chose = "N" if _default(argv, cap, out) > 1 else "1"
            best = min(r1["wall"], rn["wall"])
            ok = "yes" if rd["wall"] <= best * 1.05 else "no"
            print(f"{name:15s} {label:12s} {r1['wall']:6.1f} {rn['wall']:6.1f} {rd['wall']:6.1f} {chose:>4s} {ok:>5s} "
                  f"{r1['cpu']:4.1f}/{rn['cpu']:4.1f}/{rd['cpu']:4.1f} "
                  f"{r1['largest']:4.0f}/{rn['largest']:4.0f}/{rd['largest']:4.0f}     {rd['total']:10.0f} "
                  f"{'yes' if rd['largest'] < 100 else 'NO':>4s}", flush=True)
    print(f"--jobs N = {jobs}; load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
