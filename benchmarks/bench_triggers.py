"""Triggers over a simulated day: the RSS curve hour by hour and the throughput of `replay --trigger --ring`.

    .venv/bin/python benchmarks/bench_triggers.py [--hours 24] [--scenario tds-v8] [--poll-ms 1000] [--keep DIR]

1. Generate (not timed) `--hours` of a simulated line with `sniffer simulate` (default: two TDS-V8
   drives polled every second, each tripping every 10-30 minutes, at 9600 8N2; EEPROM-save
   exceptions every 20 polls), as a field capture of a day would be.
2. In a fresh process each (`--run`), the same session `sniffer replay` runs, built from the
   command line by sniffer.cli, with a probe sink that records VmRSS (and the wall time) at every
   capture hour:
     triggers   --quiet --ring --trigger fault --trigger 'rate(fault) >= 2/5s' --pre 5m --post 1m
     busy       the same plus --trigger 'rate(exc) >= 3/min' (true most of the time: windows capped
                at --max-window, the ring and a window written at once all day)
     peer       --quiet, no triggers (what the triggers add)
3. Prints per run: frames, wall s, frames/s, peak RSS (VmHWM), the RSS at capture hours 1, 2, 4, 8,
   12, 16, 20, 23 and at the end, windows written and their bytes.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_pipeline as bp  # noqa: E402 - machine and revision lines

HOUR_NS = 3600 * 10**9
TRIGGERS = ["--trigger", "fault", "--trigger", "rate(fault) >= 2/5s", "--pre", "5m", "--post", "1m", "--ring"]
RUNS = {
    "triggers": TRIGGERS,
    "busy": TRIGGERS + ["--trigger", "rate(exc) >= 3/min"],
    "peer": [],
}


def _status(key: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key):
                return int(line.split()[1])
    return 0


class Probe:
    """A sink that notes VmRSS at each capture hour (the frames' own time)."""

    def __init__(self) -> None:
        self.t0 = 0
        self.next_ns = HOUR_NS
        self.curve: list[tuple[int, float, float]] = []  # (hour, RSS MB, wall s)
        self.began = time.monotonic()
        self.frames = 0

    def start(self, info) -> None:
        self.t0 = info.t0_ns

    def raw(self, ev) -> None:
        pass

    def frame(self, f) -> None:
        self.frames += 1
        if f.t_ns - self.t0 >= self.next_ns:
            self.curve.append((self.next_ns // HOUR_NS, _status("VmRSS:") / 1024, time.monotonic() - self.began))
            self.next_ns += HOUR_NS

    def close(self) -> None:
        pass


def child(path: str, folder: str, flags: list[str]) -> None:
    from sniffer.cli import build_parser
    from sniffer.capture.session import Session
    from sniffer.capture.settings import CaptureSpec
    from sniffer.sources.files import FileSource

    args = build_parser().parse_args(["replay", path, "--quiet", *(["--windows", folder] if flags else []), *flags])
    spec = CaptureSpec.from_args(args)
    probe = Probe()
    t = time.monotonic()
    session = Session(spec, FileSource(path), [probe])
    session.open()
    for s in session.sinks:
        if hasattr(s, "report"):
            s.report = lambda text: None
    session.run()
    wall = time.monotonic() - t
    probe.curve.append((-1, _status("VmRSS:") / 1024, wall))  # the end of the capture
    files = sorted(Path(folder).glob("*.trigger-*.mcap"))
    print(json.dumps({"frames": probe.frames, "wall": wall, "peak_mb": _status("VmHWM:") / 1024,
                      "curve": probe.curve, "windows": len(files),
                      "window_mb": sum(f.stat().st_size for f in files) / 1e6}))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=24)
    ap.add_argument("--scenario", default="tds-v8")
    ap.add_argument("--poll-ms", type=float, default=1000)
    ap.add_argument("--keep", help="keep (and reuse) the simulated capture in this folder")
    ap.add_argument("--run", nargs=3, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.run:
        child(a.run[0], a.run[1], json.loads(a.run[2]))
        return
    folder = Path(a.keep or tempfile.mkdtemp(prefix="bench-triggers-"))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"day-{a.scenario}-{a.hours:g}h-{a.poll_ms:g}ms.mcap"
    if not path.exists():
        t = time.monotonic()
        subprocess.run([sys.executable, "-m", "sniffer", "simulate", "--scenario", a.scenario, "--seed", "5",
                        "--duration", str(a.hours * 3600), "--param", f"poll_period_ms={a.poll_ms}",
                        "--param", "unit1.trip_every_s=(600.0, 1800.0)",
                        "--param", "unit2.trip_every_s=(900.0, 1800.0)",
                        "--out", str(path)], check=True, capture_output=True)
        print(f"simulated {a.hours:g} h in {time.monotonic() - t:.0f} s: {path} ({path.stat().st_size / 1e6:.0f} MB)")
    print(bp.machine())
    print(bp.revision())
    hours = [h for h in (1, 2, 4, 8, 12, 16, 20, 23) if h < a.hours] + [-1]
    print(f"{'run':9} {'frames':>8} {'wall s':>7} {'frames/s':>9} {'peak MB':>8} {'windows':>8} {'win MB':>7}  "
          + " ".join(f"{'h' + str(h) if h >= 0 else 'end':>6}" for h in hours) + "   (RSS MB at capture hour)")
    for name, flags in RUNS.items():
        out = folder / f"windows-{name}"
        out.mkdir(exist_ok=True)
        for f in out.glob("*"):
            f.unlink()
        r = subprocess.run([sys.executable, __file__, "--run", str(path), str(out), json.dumps(flags)],
                           capture_output=True, text=True, check=True)
        d = json.loads(r.stdout)
        curve = {h: mb for h, mb, _ in d["curve"]}
        print(f"{name:9} {d['frames']:>8} {d['wall']:>7.1f} {d['frames'] / d['wall']:>9.0f} {d['peak_mb']:>8.1f} "
              f"{d['windows']:>8} {d['window_mb']:>7.1f}  " + " ".join(f"{curve.get(h, 0):>6.1f}" for h in hours))
    if not a.keep:
        for p in sorted(folder.rglob("*"), reverse=True):
            p.unlink() if p.is_file() else p.rmdir()
        os.rmdir(folder)


if __name__ == "__main__":
    main()
