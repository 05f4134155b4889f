"""Memory and speed of the TUI's frame store over a million-frame replay, against keeping every Frame.

    .venv/bin/python benchmarks/bench_tui_memory.py [--frames N] [--old-frames M] [--quick]
    BENCH_MIX=stress .venv/bin/python benchmarks/bench_tui_memory.py --frames 200000 --skip-old

1. Generate (not timed) the capture bench_pipeline.py uses: its drive-poll mix with errors at
   115200 8N1, seen through the FTDI read model, at least N frames (default 1,000,000).
2. Measure, each in a fresh subprocess so one run's peak RSS does not hide another's:
   - app: what `sniffer replay FILE --tui` runs, without a terminal: SnifferApp headless
     (`run_test`, 120x40, its 15 Hz poll) with a session decoding the streamed capture on the
     feed thread (default registry; the register watch applies the frames' `writes`), until every
     frame is in the store.  Then the filters are timed on that store.
   - store: the same pipeline and TuiSink on one thread, drained into a FrameStore every 5,000
     frames (the App's max_batch), so the time in FrameStore.add is measured alone.
   - old: as `store`, but every Frame is also kept in a list with a dict index -> row, which is
     what the store held before (frames as objects); run with M frames (default N).
   Each prints: the process's peak RSS, its RSS before the first frame (imports, registry),
   bytes per frame = (peak - before) / frames, and rates.
3. The register history (sniffer/analysis/history.py) of the app and store runs: samples seen and kept,
   registers thinned, the bytes of its arrays and objects; the time to draw the plot of the 8
   registers with the most samples over the whole capture and over its last tenth (plotmodel.render,
   200 x 40 cells), and to list the busiest register's changes.  BENCH_MIX=stress makes the capture
   bench_pipeline's stress mix (125-register reads: hundreds of registers).
Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import os
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_pipeline import LINE, _info, generate, read_chunks

DRAIN = 5_000  # SnifferApp.max_batch: at most this many frames a poll tick (about 50 ms of store work)
TARGET_MB = 300


def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _current_rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _history(store) -> dict:
    """The register history's size, and what drawing the plot and listing changes cost on it."""
    from sniffer.tui.plotmodel import PALETTE, Trace, render

    hs = [rv.history for rv in store.registers.values()]
    out = {"registers": len(hs), "seen": sum(h.seen for h in hs), "kept": sum(len(h) for h in hs),
           "thinned": sum(1 for h in hs if h.thins), "most_kept": max((len(h) for h in hs), default=0),
           "array_bytes": sum(sys.getsizeof(a) for h in hs for a in (h.t, h.v, h.ix, h.fl)),
           "object_bytes": sum(sys.getsizeof(h) for h in hs)}
    busiest = sorted(store.registers.values(), key=lambda rv: -rv.history.seen)[:len(PALETTE)]
    traces = [Trace((rv.unit, rv.table, rv.address), rv.name, rv.eng_unit or "", c, rv.history)
              for rv, c in zip(busiest, PALETTE)]
    lo, hi = store.t0_ns, store.last_t_ns
    for label, (a, b) in (("plot, whole capture", (lo, hi)), ("plot, last tenth", (hi - (hi - lo) / 10, hi))):
        times = []
        for _ in range(5):
            t = time.perf_counter()
            render(traces, a, b, 200, 40, lo, cursor_ns=(a + b) / 2)
            times.append(time.perf_counter() - t)
        out[label] = sorted(times)[2]
    t = time.perf_counter()
    n = len(busiest[0].history.change_positions()) if busiest else 0
    out["change log of the busiest"] = (time.perf_counter() - t, n)
    return out


def _filters(store) -> dict:
    """Seconds per filter rebuild over the whole store, and the rows each leaves."""
    out = {}
    for label, kw in (("errors only", {"errors_only": True}),
                      ("unit 2", {"errors_only": False, "units": frozenset({2})}),
                      ("fc 16 + errors", {"units": None, "functions": frozenset({16}), "errors_only": True}),
                      ("text 'illegal'", {"functions": None, "errors_only": False, "text": "illegal"}),
                      ("text hex '0110200'", {"text": "0110200"}),
                      ("text 'holding[8449]'", {"text": "holding[8449]"}),
                      ("unit 3 + text 'crc'", {"units": frozenset({3}), "text": "crc"}),
                      ("reg:8449 lat>5ms", {"units": None, "text": "reg:8449 lat>5ms"}),
                      ("value holding[8449] >= 3000", {"text": "holding[8449] >= 3000"}),
                      ("clear", {"units": None, "text": ""})):
        t = time.perf_counter()
        store.update_filter(**kw)
        out[label] = (time.perf_counter() - t, len(store.view))
    n = len(store)
    t = time.perf_counter()
    r = n // 2
    for _ in range(1000):
        r = store.next_problem(r) or 0
    out["next error x1000"] = (time.perf_counter() - t, None)
    rng = random.Random(1)
    rows = [rng.randrange(n) for _ in range(200)]
    store.blocks.clear_cache()
    t = time.perf_counter()
    for row in rows:
        store.frame(row)
    out["200 random frames, cold"] = (time.perf_counter() - t, None)
    t = time.perf_counter()
    for row in rows:
        store.frame(row)
    out["200 random frames, cached"] = (time.perf_counter() - t, None)
    return out


# ------------------------------------------------------------ children
def child_store(folder: Path, keep_frames: bool, limit_frames: int | None) -> dict:
    from decoders.registry import default_registry
    from sniffer.capture.pipeline import Pipeline
    from sniffer.tui.store import FrameStore
    from sniffer.tui.sink import TuiSink

    registry = default_registry()
    sink = TuiSink()
    store = FrameStore()
    kept: list = []
    row_of: dict = {}
    gc.collect()
    rss0 = _current_rss_mib()
    t_add = 0.0
    t0 = time.perf_counter()
    p = Pipeline(_info(), LINE, registry, [sink])

    def drain():
        nonlocal t_add
        batch = sink.drain()
        t = time.perf_counter()
        store.add(batch)
        t_add += time.perf_counter() - t
        if keep_frames:
            for f in batch:
                row_of[f.index] = len(kept)
                kept.append(f)

    for ev in read_chunks(folder / "chunks.bin"):
        p.feed(ev)
        if sink.backlog >= DRAIN:
            drain()
            if limit_frames and len(store) >= limit_frames:
                break
    p.finish()
    drain()
    wall = time.perf_counter() - t0
    res = {"frames": len(store), "rss_before": rss0, "rss_peak": _rss_mib(), "rss_end": _current_rss_mib(),
           "wall": wall, "add_s": t_add, "packed_bytes": store.blocks.packed_bytes,
           "registers": len(store.registers), "units": len(store.units)}
    if not keep_frames:
        res["history"] = _history(store)
        res["filters"] = _filters(store)
    return res


def child_app(folder: Path) -> dict:
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.tui.run import session_app
    from sniffer.tui.sink import TuiSink

    sink = TuiSink()
    session = Session(CaptureSpec(), EventSource(_info(), read_chunks(folder / "chunks.bin")), [sink])
    session.open()
    app = session_app(session, sink, source_label="bench")
    res: dict = {}

    async def go():
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.pause(0.1)
            gc.collect()
            res["rss_before"] = _current_rss_mib()
            t0 = time.perf_counter()
            while not (app.caught_up and len(app.store) == app.sink.frames_in):
                await pilot.pause(0.2)
            res["wall"] = time.perf_counter() - t0
            await pilot.press("3")  # the register watch over the whole shadow
            await pilot.pause(0.3)
            await pilot.press("1", "home")
            await pilot.pause(0.1)
            res["rss_peak"] = _rss_mib()
            res["rss_end"] = _current_rss_mib()
            res["frames"] = len(app.store)
            res["registers"] = len(app.store.registers)
            res["packed_bytes"] = app.store.blocks.packed_bytes
            res["history"] = _history(app.store)
            res["filters"] = _filters(app.store)
            await pilot.press("q")

    asyncio.run(go())
    if app.feed_error is not None:
        raise app.feed_error
    return res


def run_child(kind: str, folder: Path, limit: int | None = None) -> dict:
    cmd = [sys.executable, __file__, "--child", kind, "--folder", str(folder)]
    if limit:
        cmd += ["--limit", str(limit)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------ report
def _line(label: str, r: dict) -> str:
    n = r["frames"]
    grown = max(r["rss_peak"] - r["rss_before"], 0.0)
    if r.get("add_s"):
        rate = f"{n / r['add_s']:,.0f} frames/s into the store"
    else:
        rate = f"{n / r['wall']:,.0f} frames/s end to end"
    return (f"{label:<34} {n:>10,} {r['rss_peak']:>9.1f} {r['rss_before']:>9.1f} {grown * 2**20 / n:>9.0f} "
            f"{r['wall']:>7.1f}s  {rate}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--old-frames", type=int, default=None, help="frames for the old-approach run (default --frames)")
    ap.add_argument("--quick", action="store_true", help="100,000 frames")
    ap.add_argument("--skip-app", action="store_true")
    ap.add_argument("--skip-old", action="store_true")
    ap.add_argument("--child")
    ap.add_argument("--folder")
    ap.add_argument("--limit", type=int)
    a = ap.parse_args()
    if a.child:
        folder = Path(a.folder)
        if a.child == "app":
            res = child_app(folder)
        else:
            res = child_store(folder, a.child == "old", a.limit)
        print(json.dumps(res))
        return
    n = 100_000 if a.quick else a.frames
    old_n = a.old_frames or n
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(prefix="bench_tui_mem_") as tmp:
        folder = Path(tmp)
        meta = generate(n, folder)
        print(f"capture: {meta['scenario']} {meta['line']}, {meta['truth_frames']:,} wire frames, "
              f"{meta['bytes'] / 1e6:.1f} MB in {meta['chunks']:,} reads (generated in {meta['gen_s']} s, not timed)")
        results = {}
        for kind in (() if a.skip_app else ("app",)) + ("store",) + (() if a.skip_old else ("old",)):
            results[kind] = run_child(kind, folder, old_n if kind == "old" else None)
            print(f"  {kind}: done", flush=True)
    print(f"\n{'run':<34} {'frames':>10} {'peak MiB':>9} {'start MiB':>9} {'B/frame':>9} {'wall':>8}")
    labels = {"app": "app: replay --tui, headless", "store": "store: pipeline + FrameStore",
              "old": "old: + every Frame kept"}
    for kind, r in results.items():
        print(_line(labels[kind], r))
    for kind, r in results.items():
        if "packed_bytes" in r and kind != "old":
            print(f"{kind}: packed frames + search text {r['packed_bytes'] / r['frames']:.0f} B/frame; "
                  f"{r['registers']} registers in the watch")
    if "app" in results:
        r = results["app"]
        print(f"target: whole process under {TARGET_MB} MB for the replay: "
              f"{'ok' if r['rss_peak'] < TARGET_MB else 'ABOVE'} ({r['rss_peak']:.0f} MiB peak)")
    if "old" in results:
        old, new = results["old"], results["store"]
        per_old = (old["rss_peak"] - old["rss_before"]) * 2**20 / old["frames"]
        per_new = (new["rss_peak"] - new["rss_before"]) * 2**20 / new["frames"]
        print(f"old / new bytes per frame: {per_old / per_new:.1f}x; old extrapolated to {n:,} frames: "
              f"{old['rss_before'] + per_old * n / 2**20:,.0f} MiB")
    for kind in ("app", "store"):
        if kind in results:
            h = results[kind]["history"]
            print(f"\nregister history of the {kind} run: {h['registers']:,} registers, {h['seen']:,} samples seen, "
                  f"{h['kept']:,} kept ({h['thinned']:,} registers thinned, at most {h['most_kept']:,} a register): "
                  f"arrays {h['array_bytes'] / 2**20:.1f} MiB + objects {h['object_bytes'] / 2**20:.2f} MiB")
            for label in ("plot, whole capture", "plot, last tenth"):
                print(f"  {label + ' (8 registers, 200x40)':<44} {h[label] * 1e3:8.1f} ms")
            dt, changes = h["change log of the busiest"]
            print(f"  {'change log of the busiest register':<44} {dt * 1e3:8.1f} ms  -> {changes:,} changes")
    for kind in ("app", "store"):
        if kind in results:
            print(f"\nfilters on the {kind} run's store ({results[kind]['frames']:,} frames):")
            for label, (dt, rows) in results[kind]["filters"].items():
                print(f"  {label:<28} {dt * 1e3:8.1f} ms" + (f"  -> {rows:,} rows" if rows is not None else ""))


if __name__ == "__main__":
    main()
