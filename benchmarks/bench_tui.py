"""The TUI under load: key-to-screen latency and CPU on a real terminal (headline), and in-process figures.

    .venv/bin/python benchmarks/bench_tui.py [--sections terminal,inprocess] [--keys 80] [--repeat 1]
                                             [--before DIR] [--rates 1000,2000,5000,10000,20000]
                                             [--seconds 3] [--million] [--quick]
    .venv/bin/python benchmarks/bench_tui.py --browser [--presses 50]

Section "terminal" (the headline figures; benchmarks/tui_terminal.py, which runs alone too): the real
commands on a pty, the screen kept by pyte, keys typed and timed until the screen shows their effect,
under `sniffer demo --scenario stress` (the capture in its own process) and while a 200k-frame replay
loads, against the same keys on an idle replay; the CPU of the TUI and of the capture child under live
stress against the capture alone (headless).  `--before DIR` runs a second checkout's sniffer (a
worktree of the commit before a change) in the same run, for before / after on one machine load.

Section "inprocess" (how many frames per second the App absorbs): a feeder thread pushes synthetic frames
(decoded frames of captures/sim/errors.mcap and a510.mcap, renumbered) into the TuiSink at a fixed rate,
in 10 ms batches, as the capture thread would; the App runs headless under `run_test` (120x40) with its
15 Hz poll timer.  For each rate it prints: frames absorbed per second, the backlog left in the sink, the
time one poll tick or intake turn takes (the UI thread's longest stretches), and the latency of key
presses (Pilot press -> handled) while frames keep arriving: it leaves out drawing and the terminal.
`--million` also loads 1,000,000 frames into a FrameStore and times filters, next-error and
drawing rows in the middle.

`--browser` measures the browser view instead: `sniffer serve --demo --scenario stress` (capture,
web server and one viewer per tab, each a process) with headless Chromium on its page
(tests/headless_chromium.py, Debian's chromium).  It presses 2 and 1 in turn (Units tab, Frames tab)
and times, in the page, from the key's keydown to the first write to the page's terminal after
which the new tab's header is on screen; it prints median, p99 and max over the presses, and the
CPU share of the viewer, the capture and Chromium meanwhile.  Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import asyncio
import copy
import gc
import os
import resource
import signal
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from tui_helpers import key_latency, replay_frames

import tui_terminal

from sniffer.tui.app import SnifferApp
from sniffer.tui.store import FrameStore
from sniffer.tui.sink import TuiSink


def synthetic(n: int):
    """n frames cloned from real decoded ones, renumbered, pairs kept consistent."""
    pool = list(replay_frames("errors.mcap")[1]) + list(replay_frames("a510.mcap")[1])
    span = len(pool)
    period = max(f.t_ns for f in pool) + 10_000_000
    out = []
    for i in range(n):
        src = pool[i % span]
        k = i // span
        f = copy.copy(src)
        first_half = i % span < len(replay_frames("errors.mcap")[1])
        f.index = src.index + k * 100_000 + (0 if first_half else 50_000)
        if src.pair is not None:
            f.pair = f.index - src.index + src.pair
        f.t_ns = src.t_ns + k * period
        out.append(f)
    return out


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


async def run_rate(rate: int, seconds: float, frames: list) -> dict:
    sink = TuiSink()
    sink.start(replay_frames("errors.mcap")[0])
    app = SnifferApp(sink, None, poll_hz=15)
    tick_times: list[float] = []  # poll ticks and intake turns: the UI thread's stretches away from keys

    def timed(turn):
        def run():
            t = time.perf_counter()
            turn()
            tick_times.append(time.perf_counter() - t)
        return run

    app._tick, app._intake = timed(app._tick), timed(app._intake)  # the timers call the attributes
    stop = threading.Event()
    sent = [0]

    def feeder():
        batch_s = 0.01
        per = max(int(rate * batch_s), 1)
        t_next = time.perf_counter()
        i = 0
        while not stop.is_set() and i < len(frames):
            sink.frames(frames[i:i + per])
            i += per
            sent[0] = i
            t_next += per / rate
            d = t_next - time.perf_counter()
            if d > 0:
                time.sleep(d)

    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.pause(0.2)
        th = threading.Thread(target=feeder, daemon=True)
        t0 = time.perf_counter()
        th.start()
        n0 = len(app.store)
        lat = []
        k = 0
        while time.perf_counter() - t0 < seconds:
            await pilot.pause(0.15)
            lat.append(await key_latency(app, pilot, "up" if k % 2 else "home"))
            k += 1
        elapsed = time.perf_counter() - t0
        absorbed = len(app.store) - n0
        stop.set()
        th.join()
        backlog = sink.backlog
    return {
        "rate": rate, "sent_per_s": sent[0] / elapsed, "absorbed_per_s": absorbed / elapsed,
        "backlog": backlog, "tick_med_ms": 1e3 * statistics.median(tick_times) if tick_times else 0,
        "tick_max_ms": 1e3 * max(tick_times) if tick_times else 0, "ticks_per_s": len(tick_times) / elapsed,
        "key_med_ms": 1e3 * statistics.median(lat), "key_max_ms": 1e3 * max(lat), "keys": len(lat),
    }


def million(n: int) -> None:
    print(f"\n{n:,} frames in a FrameStore (no Textual)")
    frames = synthetic(n)
    gc.collect()
    r0 = rss_mb()
    s = FrameStore()
    t = time.perf_counter()
    for i in range(0, n, 5000):
        s.add(frames[i:i + 5000])
    dt = time.perf_counter() - t
    print(f"  add:            {dt:6.2f} s  ({n / dt:,.0f} frames/s)  peak RSS +{rss_mb() - r0:.0f} MB "
          f"(frames themselves were built before)")
    for label, kw in (("errors only", {"errors_only": True}),
                      ("unit 2", {"errors_only": False, "units": frozenset({2})}),
                      ("text 'ILLEGAL'", {"units": None, "text": "ILLEGAL"}), ("clear", {"text": ""})):
        t = time.perf_counter()
        s.update_filter(**kw)
        print(f"  filter {label:15s} {time.perf_counter() - t:6.3f} s -> {len(s.view):,} rows")
    t = time.perf_counter()
    r = n // 2
    for _ in range(1000):
        r = s.next_problem(r)
    print(f"  next error x1000: {1e3 * (time.perf_counter() - t):.1f} ms")

    async def draw():
        sink = TuiSink()
        app = SnifferApp(sink, None)
        app.store = s
        async with app.run_test(size=(120, 40)) as pilot:
            app.frame_list.store = s
            app.frame_list.follow = False
            app.frame_list.refresh_rows()
            await pilot.pause()
            t = time.perf_counter()
            app.frame_list.select_row(n // 2)
            await pilot.pause()
            lat = []
            for key in ("up", "home", "up", "home"):
                lat.append(await key_latency(app, pilot, key))
            print(f"  jump to middle: {1e3 * (time.perf_counter() - t):.0f} ms (incl. keys); "
                  f"keys median {1e3 * statistics.median(lat):.0f} ms max {1e3 * max(lat):.0f} ms")

    asyncio.run(draw())


def cpu_seconds(pids: list[int]) -> float:
    """User + system CPU time the processes have used so far."""
    total = 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rpartition(")")[2].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime (clock ticks)
    return total / os.sysconf("SC_CLK_TCK")


async def browser_presses(port: int, sock: str, profile: str, presses: int) -> dict:
    from headless_chromium import Chromium
    from serve_helpers import processes_in_session, processes_with

    async with await Chromium.launch(profile) as browser:
        await browser.open(f"http://127.0.0.1:{port}/")
        await browser.wait_for(lambda s: "->REQ" in s, "frames in the frame list")
        tabs = [("2", "lat med"), ("1", "frame→pair")]  # the Units tab's header, the Frames tab's
        for key, marker in tabs:  # warm up: both tabs drawn once
            await browser.key_to_text(key, marker)
        who = {"viewer": processes_with(f"attach {sock} --tui"), "capture": processes_with(f"--publish {sock}"),
               "publisher": processes_with("sniffer.processes.publisher"),
               "chromium": processes_in_session(browser.proc.pid) + processes_with(profile)}
        cpu0, t0 = {k: cpu_seconds(v) for k, v in who.items()}, time.perf_counter()
        lat = []
        for i in range(presses):
            await asyncio.sleep(0.2)
            lat.append(await browser.key_to_text(*tabs[i % 2]))
        elapsed = time.perf_counter() - t0
        cpu = {k: (cpu_seconds(v) - cpu0[k]) / elapsed for k, v in who.items()}
        screen = await browser.screen()
    rate = [line for line in screen.splitlines() if " fr/s " in line]
    return {"lat": lat, "cpu": cpu, "status": rate[0].strip() if rate else "?"}


def browser(presses: int) -> None:
    from serve_helpers import start_serve

    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs; browser view: sniffer serve --demo --scenario "
          f"stress, headless Chromium 1400x900, {presses} presses of 2 / 1 (Units / Frames), 0.2 s apart")
    with tempfile.TemporaryDirectory() as tmp:
        sock = f"{tmp}/bench.sock"
        proc, port = start_serve(Path(tmp), "--demo", "--scenario", "stress", "--no-out", "--socket", sock,
                                 log=Path(tmp) / "serve.log")
        try:
            r = asyncio.run(browser_presses(port, sock, f"{tmp}/chromium", presses))
        finally:
            proc.send_signal(signal.SIGINT)
            proc.wait(60)
    for what, lat in (("both", r["lat"]), ("2 Units", r["lat"][0::2]), ("1 Frames", r["lat"][1::2])):
        lat = sorted(lat)
        p99 = statistics.quantiles(lat, n=100, method="inclusive")[98]
        print(f"  key -> screen text (in the page), {what:8s}: median {statistics.median(lat):4.0f} ms, "
              f"p99 {p99:4.0f} ms, min {lat[0]:4.0f} ms, max {lat[-1]:4.0f} ms")
    print("  CPU, share of one core: " + ", ".join(f"{k} {100 * v:.0f} %" for k, v in r["cpu"].items()))
    print(f"  status bar at the end: {r['status']}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sections", default="terminal,inprocess", help="terminal (headline), inprocess")
    ap.add_argument("--keys", type=int, default=80, help="terminal: keys per scenario")
    ap.add_argument("--repeat", type=int, default=1, help="terminal: runs of every scenario")
    ap.add_argument("--before", metavar="DIR", help="terminal: also run the sniffer of checkout DIR in each run")
    ap.add_argument("--rates", default="1000,2000,5000,10000,20000")
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--million", action="store_true")
    ap.add_argument("--quick", action="store_true", help="2 rates, 2 s each, 200k-frame store")
    ap.add_argument("--browser", action="store_true", help="the browser view's key latency instead (Chromium)")
    ap.add_argument("--presses", type=int, default=50, help="with --browser: key presses timed (default 50)")
    a = ap.parse_args()
    if a.browser:
        browser(a.presses)
        return
    sections = a.sections.split(",")
    if "terminal" in sections:
        print("== key-to-screen latency and CPU on a terminal (benchmarks/tui_terminal.py)")
        tui_terminal.main(["--keys", str(a.keys), "--repeat", str(a.repeat)]
                          + (["--before", a.before] if a.before else []))
    if "inprocess" not in sections:
        return
    print("\n== in-process: frames absorbed and keys handled (App headless under run_test, no terminal)")
    rates = [int(x) for x in a.rates.split(",")]
    if a.quick:
        rates, a.seconds = [2000, 5000], 2.0
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs; App headless 120x40, poll 15 Hz")
    need = int(max(rates) * (a.seconds + 1))
    frames = synthetic(need)
    print(f"{'rate':>7} {'sent/s':>8} {'absorbed/s':>10} {'backlog':>8} {'tick med':>9} {'tick max':>9} "
          f"{'ticks/s':>7} {'key med':>8} {'key max':>8}")
    for rate in rates:
        r = asyncio.run(run_rate(rate, a.seconds, frames))
        print(f"{r['rate']:>7} {r['sent_per_s']:>8.0f} {r['absorbed_per_s']:>10.0f} {r['backlog']:>8} "
              f"{r['tick_med_ms']:>7.1f}ms {r['tick_max_ms']:>7.1f}ms {r['ticks_per_s']:>7.1f} "
              f"{r['key_med_ms']:>6.0f}ms {r['key_max_ms']:>6.0f}ms")
    if a.million or a.quick:
        million(200_000 if a.quick else 1_000_000)


if __name__ == "__main__":
    main()
