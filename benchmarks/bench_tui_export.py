"""The TUI's export (x) of a 200k-frame view and how the UI answers keys meanwhile; the cost of the byte view's reads.

    .venv/bin/python benchmarks/bench_tui_export.py [--frames 200000]

For each format (MCAP, pcap, CSV) the App (headless 120x40, 15 Hz poll) holds N
synthetic frames (bench_tui.synthetic), the export modal is filled and Enter
pressed; while the worker thread writes, arrow keys are pressed and timed as in
bench_tui.py (key posted -> the cursor moved).  Printed: the export's wall time,
frames/s, the file size, key latency median / max during it.  Then the cost of
marking reads with their frames (sniffer.analysis.reads.ReadMarker, on the capture
thread of an in-process replay, in the publisher process of `--publish`), per
frame and per read, over the simulated captures.  Figures are printed, nothing
is asserted.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_tui import key_latency, synthetic
from tui_helpers import SIM, replay_frames

from sniffer.events import Chunk
from sniffer.analysis.reads import ReadMarker
from sniffer.sources.files import open_replay
from sniffer.tui.app import SnifferApp
from sniffer.tui.export import FORMATS
from sniffer.tui.sink import TuiSink


async def export_run(frames: list, fmt: str, folder: str) -> dict:
    sink = TuiSink()
    sink.start(replay_frames("errors.mcap")[0])
    sink.frames(frames)
    sink.close()
    app = SnifferApp(sink, None, capture_path=os.path.join(folder, "big.mcap"), max_batch=len(frames))
    async with app.run_test(size=(120, 40)) as pilot:
        app.poll()
        await pilot.pause()
        await pilot.press("x")
        screen = app.screen
        if fmt != "mcap":
            await pilot.press("shift+tab", *["right"] * list(FORMATS).index(fmt), "enter", "tab")
        path = screen.query_one("#export-path").value
        t, cpu = time.perf_counter(), time.process_time()
        await pilot.press("enter")
        lat = []
        k = 0
        while app.export_status is not None:
            lat.append(await key_latency(app, pilot, "up" if k % 2 else "home"))
            k += 1
            await pilot.pause(0.05)
        await app.workers.wait_for_complete()
        dt, cpu = time.perf_counter() - t, time.process_time() - cpu
        size = sum(os.path.getsize(p) for p in (path, path[:-4] + ".points.csv") if os.path.exists(p))
    return {"fmt": fmt, "s": dt, "cpu": cpu, "fps": len(frames) / dt, "mb": size / 1e6, "keys": len(lat),
            "key_med": 1e3 * statistics.median(lat) if lat else 0.0, "key_max": 1e3 * max(lat) if lat else 0.0}


def marking() -> None:
    print("\nreads marked with their frames (ReadMarker), best of 3 passes over 50 repeats of each capture")
    for name in sorted(p.name for p in SIM.glob("*.mcap")):
        _, events = open_replay(str(SIM / name))
        chunks = [ev for ev in events if type(ev) is Chunk]
        _, frames, _ = replay_frames(name)
        best = None
        for _ in range(3):
            m = ReadMarker()
            t = time.perf_counter()
            for _ in range(50):
                for c in chunks:
                    m.chunk(c)
                for f in frames:
                    m.frame(f.index, len(f.raw))
            dt = time.perf_counter() - t
            best = dt if best is None else min(best, dt)
        n = 50 * len(frames)
        print(f"  {name:22s} {1e6 * best / n:5.2f} us a frame ({len(chunks) / len(frames):.2f} reads a frame)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=200_000)
    a = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} "
          "(wall times move with it; CPU is the process's, UI and worker); App headless 120x40, poll 15 Hz")
    frames = synthetic(a.frames)
    print(f"export of a {a.frames:,}-frame view; keys pressed while the worker writes")
    print(f"{'format':>7} {'wall':>7} {'CPU':>7} {'frames/s':>9} {'size':>8} {'keys':>5} {'key med':>8} {'key max':>8}")
    with tempfile.TemporaryDirectory() as folder:
        for fmt in FORMATS:
            r = asyncio.run(export_run(frames, fmt, folder))
            print(f"{r['fmt']:>7} {r['s']:6.1f}s {r['cpu']:6.1f}s {r['fps']:9,.0f} {r['mb']:6.1f}MB {r['keys']:5d} "
                  f"{r['key_med']:6.0f}ms {r['key_max']:6.0f}ms")
    marking()


if __name__ == "__main__":
    main()
