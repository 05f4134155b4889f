"""How fast the TUI opens a capture file: `sniffer replay CAP --tui`'s session and App, headless, in-process.

    .venv/bin/python benchmarks/bench_tui_open.py CAP [--keys 40] [--profile OUT.prof]
    .venv/bin/python benchmarks/bench_tui_open.py --make 1000000     # the capture: simulate --scenario stress

The replay command's own session (CaptureSpec from `replay CAP`, its file source, a TuiSink) runs under the
App (`run_test`, 120x40) as `replay --tui` runs it.  Printed: the seconds from the App's start to [ended]
(every frame the replay decoded is in the store: `App.caught_up`), frames per second, the process's CPU
seconds, and when the register book and the diagnosis had caught up with the list (FrameStore.catch_up);
and while it loads, the latency of Home / End presses (posted to handled, tui_helpers.key_latency:
drawing and the terminal left out, tui_terminal.py has those) and the longest stretch the event loop was
away (a 5 ms timer's lateness: what any key would have waited at most).  Figures only, nothing asserted.
A pty run with drawing: benchmarks/tui_terminal.py (bench_side_by_side.py's TUI row).
"""

from __future__ import annotations

import argparse
import asyncio
import cProfile
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))

from tui_helpers import key_latency  # noqa: E402

PER_S = 372  # the stress scenario's frames per bus second


def make(frames: int, out: Path) -> Path:
    duration = frames // PER_S + 1
    subprocess.run([sys.executable, "-m", "sniffer", "simulate", "--scenario", "stress", "--duration",
                    str(duration), "--seed", "7", "--out", str(out)], check=True)
    return out


async def _lag(samples: list[float], stop: asyncio.Event, period: float = 0.005) -> None:
    loop = asyncio.get_running_loop()
    while not stop.is_set():
        t = loop.time()
        await asyncio.sleep(period)
        samples.append(loop.time() - t - period)


def open_capture(path: str, n_keys: int, profile: str | None) -> dict:
    from sniffer.capture.session import Session
    from sniffer.capture.settings import CaptureSpec
    from sniffer.commands import build_parser
    from sniffer.sources.segset import replay_source
    from sniffer.tui.run import _ready_interpreter, session_app
    from sniffer.tui.sink import TuiSink

    spec = CaptureSpec.from_args(build_parser().parse_args(["replay", path, "--tui"]))
    sink = TuiSink()
    session = Session(spec, replay_source(spec), [sink])
    session.open()
    app = session_app(session, sink, source_label=path, source_path=path)
    _ready_interpreter()
    res: dict = {}
    slow: list[tuple[str, float, int]] = []  # (what, seconds, store rows) of the UI thread's turns over 50 ms

    def timed(name, fn):
        def run(*a, **kw):
            t = time.perf_counter()
            out = fn(*a, **kw)
            dt = time.perf_counter() - t
            if dt > 0.05:
                slow.append((name, dt, len(app.store)))
            return out
        return run

    app._tick = timed("poll tick", app._tick)
    app._take = timed("store batch", app._take)
    res["slow"] = slow
    prof = cProfile.Profile() if profile else None

    import gc

    collections: list[tuple[int, float]] = []  # (generation, seconds) of each collection while it loads
    started: list[float] = []

    def on_gc(phase, info):
        if phase == "start":
            started.append(time.thread_time())
        elif started:
            collections.append((info["generation"], time.thread_time() - started.pop()))

    async def go():
        lag: list[float] = []
        stop = asyncio.Event()
        async with app.run_test(size=(120, 40)) as pilot:
            t0, c0 = time.perf_counter(), time.process_time()
            if prof:
                prof.enable()
            lagger = asyncio.create_task(_lag(lag, stop))
            gc.callbacks.append(on_gc)
            keys: list[float] = []
            k = 0
            while not app.caught_up:
                await asyncio.sleep(0.3)
                if len(keys) < n_keys and len(app.store) > 100:
                    keys.append(await key_latency(app, pilot, "end" if k % 2 else "home"))
                    k += 1
            res["wall"] = time.perf_counter() - t0
            res["cpu"] = time.process_time() - c0
            gc.callbacks.remove(on_gc)
            res["gc"] = collections
            if prof:
                prof.disable()
            stop.set()
            await lagger
            res["frames"] = len(app.store)
            while app.store.books_behind:  # the register book and the diagnosis catch up after the list
                await asyncio.sleep(0.3)
            res["books_wall"] = time.perf_counter() - t0
            res["books_cpu"] = time.process_time() - c0
            res["keys"] = keys
            res["lag"] = lag
            await pilot.press("q")

    asyncio.run(go())
    if prof:
        prof.dump_stats(profile)
    if app.feed_error is not None:
        raise app.feed_error
    return res


def _q(xs: list[float], p: int) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(len(xs) * p / 100))] if xs else float("nan")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("capture", nargs="?")
    ap.add_argument("--keys", type=int, default=40, help="Home / End presses timed while it loads")
    ap.add_argument("--profile", metavar="OUT", help="cProfile the load into OUT")
    ap.add_argument("--make", type=int, metavar="FRAMES", help="make a stress capture of about FRAMES frames")
    ap.add_argument("--out", default="stress.mcap", help="with --make: where")
    args = ap.parse_args(argv)
    if args.make:
        print(make(args.make, Path(args.out)))
        return
    if not args.capture:
        ap.error("give a capture (or --make FRAMES)")
    import os

    r = open_capture(args.capture, args.keys, args.profile)
    n, keys, lag = r["frames"], [k * 1e3 for k in r["keys"]], [x * 1e3 for x in r["lag"]]
    print(f"{args.capture}: {n:,} frames on the list in {r['wall']:.1f} s ({n / r['wall']:,.0f} frames/s), "
          f"CPU {r['cpu']:.1f} s, load {os.getloadavg()[0]:.1f}")
    print(f"  the register book and the diagnosis caught up at {r['books_wall']:.1f} s, CPU {r['books_cpu']:.1f} s")
    if keys:
        print(f"  keys while loading: {len(keys)}, median {statistics.median(keys):.0f} ms, p90 {_q(keys, 90):.0f}, "
              f"max {max(keys):.0f}")
    for name in sorted({w for w, _, _ in r["slow"]}):
        ts = [(t * 1e3, n) for w, t, n in r["slow"] if w == name]
        print(f"  UI turns over 50 ms: {name} x{len(ts)}: " + ", ".join(f"{t:.0f} ms at {n}" for t, n in ts[:8]))
    for gen in (0, 1, 2):
        ts = [t * 1e3 for g, t in r["gc"] if g == gen]
        if ts:
            print(f"  gc generation {gen}: {len(ts)} collections, {sum(ts):.0f} ms in all, longest {max(ts):.0f} ms")
    if lag:
        print(f"  event loop away: median {statistics.median(lag):.1f} ms, p99 {_q(lag, 99):.0f}, max {max(lag):.0f}")


if __name__ == "__main__":
    main()
