"""A simulated day of unattended capture, faster than real time: memory per segment (issue 12, part 3).

    .venv/bin/python benchmarks/bench_unattended.py                     # 24 h, --rotate 1h (about 10 min)
    .venv/bin/python benchmarks/bench_unattended.py --quick             # 2 h, --rotate 10m
    .venv/bin/python benchmarks/bench_unattended.py --child rotated --duration 1800 --rotate 60s --json

The capture runs the session code a live capture runs (Session, the pipeline, the segment sink with its
index and --keep, the status file) over the simulator's bus (`sniffer simulate --rotate` does the same),
each run in a fresh process so one run's peak RSS cannot hide another's:

* rotated: MCAP segments (--rotate, --keep 12 by default: deletion is exercised too);
* single: the same capture into one MCAP file (no rotation): what rotation costs;
* python-can: the peer (python-can rotates log files): `can.SizedRotatingLogger` writing one CAN FD
  message per frame of the same simulated bus (raw bytes, cut to 64) to candump .log files rotated at
  the size of our segments.  It only writes; it neither frames nor decodes.

Printed: the memory curve (RSS, MiB, when each of the day's hours closed), the peak RSS, frames and
wall time.  `--json` (with --child) prints the samples for tests/test_unattended_live.py, which checks a
shorter run's RSS does not grow with segments.  Nothing is asserted here: tests never assert times.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

_PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_mib() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * _PAGE / 2**20


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class Probe:
    """A sink sampling RSS (and the objects the garbage collector tracks) each time the capture passes a
    sample boundary (a segment's span)."""

    def __init__(self, every_ns: int) -> None:
        self.every_ns = every_ns
        self.samples: list[dict] = []
        self.frames = 0
        self._next = every_ns
        self._t0 = 0
        self._start = time.monotonic()

    def start(self, info) -> None:
        self._t0 = info.t0_ns

    def raw(self, event) -> None:
        pass

    def frame(self, f) -> None:
        self.frames += 1
        if f.t_ns - self._t0 >= self._next:
            self._next += self.every_ns
            self.sample((f.t_ns - self._t0) / 1e9)

    def sample(self, t_s: float) -> None:
        self.samples.append({"t_h": round(t_s / 3600, 3), "frames": self.frames, "rss_mib": round(rss_mib(), 1),
                             "objects": len(gc.get_objects()), "wall_s": round(time.monotonic() - self._start, 1)})

    def close(self) -> None:
        pass


def child(mode: str, args) -> dict:
    from sniffer.formats.mcap.segments import Keep, Rotate
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.simulator.sources import SimulatedSource, scenario_named

    scenario = scenario_named(args.scenario)
    rotate = Rotate.parse([args.rotate])
    folder = tempfile.mkdtemp(prefix="bench-unattended-")
    probe = Probe(rotate.span_ns or 3600 * 10**9)
    t = time.monotonic()
    try:
        if mode == "python-can":
            return _python_can(scenario, args, folder, probe)
        source = SimulatedSource(scenario, scenario.line, args.duration, 1, "usb")
        if mode == "rotated":
            from sniffer.formats.mcap.rotating import SegmentPlan

            keep = Keep.parse([args.keep]) if args.keep else None
            spec = CaptureSpec(out=os.path.join(folder, "day"), rotate=rotate, keep=keep)
            sinks = [SegmentPlan(spec.out, rotate, keep), probe]
        else:
            from sniffer.formats import FileSink

            spec = CaptureSpec(out=os.path.join(folder, "day.mcap"))
            sinks = [FileSink("mcap", spec.out), probe]
        session = Session(spec, source, sinks, keep_partial=True, label=f"bench {mode}")
        session.run()
        probe.sample(args.duration)
        files = [os.path.join(r, f) for r, _, fs in os.walk(folder) for f in fs if f.endswith(".mcap")]
        return {"mode": mode, "frames": session.frames_out, "samples": probe.samples, "peak_mib": round(peak_mib(), 1),
                "wall_s": round(time.monotonic() - t, 1), "files": len(files),
                "bytes": sum(os.path.getsize(f) for f in files), "error": session.error}
    finally:
        import shutil

        shutil.rmtree(folder, ignore_errors=True)


def _python_can(scenario, args, folder: str, probe: Probe) -> dict:
    import can

    from sniffer.simulator.bus import simulate

    t = time.monotonic()
    seg_bytes = args.peer_bytes
    logger = can.SizedRotatingLogger(base_filename=os.path.join(folder, "day.log"), max_bytes=seg_bytes)
    n = 0
    for wf in simulate(scenario, scenario.line, args.duration, 1):
        data = bytes(wf.raw[:64])
        logger.on_message_received(can.Message(timestamp=wf.t_ns / 1e9, arbitration_id=n & 0x7FF, data=data,
                                               is_fd=True, is_extended_id=False))
        n += 1
        probe.frames = n
        if wf.t_ns >= probe._next:
            probe._next += probe.every_ns
            probe.sample(wf.t_ns / 1e9)
    logger.stop()
    probe.sample(args.duration)
    files = [os.path.join(folder, f) for f in os.listdir(folder)]
    return {"mode": "python-can", "frames": n, "samples": probe.samples, "peak_mib": round(peak_mib(), 1),
            "wall_s": round(time.monotonic() - t, 1), "files": len(files),
            "bytes": sum(os.path.getsize(f) for f in files), "error": None}


def run_child(mode: str, args, **more) -> dict:
    argv = [sys.executable, __file__, "--child", mode, "--json", "--duration", str(args.duration),
            "--rotate", args.rotate, "--scenario", args.scenario, "--keep", args.keep or ""]
    for k, v in more.items():
        argv += [f"--{k.replace('_', '-')}", str(v)]
    r = subprocess.run(argv, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{mode}: failed\n{r.stderr}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=86_400.0, help="simulated seconds (default a day)")
    ap.add_argument("--rotate", default="1h")
    ap.add_argument("--keep", default="12", help="--keep for the rotated run (default 12 segments)")
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--quick", action="store_true", help="2 simulated hours, --rotate 10m")
    ap.add_argument("--child", choices=["rotated", "single", "python-can"], help=argparse.SUPPRESS)
    ap.add_argument("--peer-bytes", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--json", action="store_true", help="with --child: print the result as JSON")
    args = ap.parse_args()
    if args.quick:
        args.duration, args.rotate = 7200.0, "10m"
    if args.child:
        result = child(args.child, args)
        print(json.dumps(result) if args.json else result)
        return
    print(f"simulated {args.duration / 3600:g} h of scenario '{args.scenario}', --rotate {args.rotate}, "
          f"--keep {args.keep or '-'}; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    runs = [run_child("rotated", args)]
    rotated = runs[0]
    runs.append(run_child("single", args))
    try:
        import can  # noqa: F401

        per_segment = max(1, rotated["bytes"] // max(1, rotated["files"]))
        runs.append(run_child("python-can", args, peer_bytes=per_segment))
    except ImportError:
        print("python-can not installed (pip install -e '.[bench]'): no peer")
    print()
    print("memory curve: RSS (MiB) as the capture passes each segment boundary")
    head = f"{'capture h':>9}  {'frames':>10}" + "".join(f"  {r['mode']:>11}" for r in runs)
    print(head)
    for i, s in enumerate(rotated["samples"]):
        cells = "".join(f"  {r['samples'][i]['rss_mib'] if i < len(r['samples']) else '-':>11}" for r in runs)
        print(f"{s['t_h']:>9}  {s['frames']:>10,}{cells}")
    print()
    print(f"{'run':<11} {'frames':>10} {'wall s':>7} {'x real time':>11} {'peak MiB':>8} {'RSS 1st->last':>14} "
          f"{'files':>5} {'MB on disk':>10}")
    for r in runs:
        first, last = r["samples"][0]["rss_mib"], r["samples"][-1]["rss_mib"]
        print(f"{r['mode']:<11} {r['frames']:>10,} {r['wall_s']:>7} {args.duration / max(r['wall_s'], 0.1):>11.0f} "
              f"{r['peak_mib']:>8} {f'{first} -> {last}':>14} {r['files']:>5} {r['bytes'] / 1e6:>10.1f}")


if __name__ == "__main__":
    main()
