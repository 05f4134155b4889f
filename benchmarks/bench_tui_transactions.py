"""The Transactions tab over a large replay: building, filtering, the histogram figures, drawing.

    .venv/bin/python benchmarks/bench_tui_transactions.py [--frames 200000]

Frames are bench_tui.synthetic's (decoded frames of errors.mcap and a510.mcap, renumbered, pairs
kept).  Prints: Transactions.add per frame (what every frame costs the store on top), the view
synced with the store's after each filter, the latency figures (first, then after one more
value: unitfigures.Latencies sorts its distinct values), formatting a screen of lines, and under
Pilot (120x40) opening tab 4 and keys in it.
Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_tui import synthetic

from sniffer.tui.app import SnifferApp
from sniffer.tui.store import FrameStore, frame_flags
from sniffer.tui.sink import TuiSink
from sniffer.tui.transactions import Transactions
from sniffer.tui.txlist import format_tx


def _ms(t0: float) -> float:
    return 1e3 * (time.perf_counter() - t0)


def model(frames) -> FrameStore:
    flags = [frame_flags(f) for f in frames]
    txs = Transactions()
    t = time.perf_counter()
    for row, f in enumerate(frames):
        txs.add(row, f, flags[row])
    dt = time.perf_counter() - t
    print(f"Transactions.add: {1e6 * dt / len(frames):.2f} µs a frame ({len(txs):,} transactions)")
    s = FrameStore(frames[0].t_ns)
    t = time.perf_counter()
    for i in range(0, len(frames), 5000):
        s.add(frames[i:i + 5000])
    print(f"FrameStore.add (transactions included): {1e6 * (time.perf_counter() - t) / len(frames):.1f} µs a frame")
    txs = s.transactions
    for label, kw in (("none", {}), ("unit 2", {"units": frozenset({2})}),
                      ("errors only", {"units": None, "errors_only": True}),
                      ("text 'ILLEGAL'", {"errors_only": False, "text": "ILLEGAL"}), ("clear", {"text": ""})):
        s.update_filter(**kw)
        t = time.perf_counter()
        txs.sync(s.view)
        print(f"  sync, filter {label:15s} {_ms(t):7.1f} ms -> {len(txs.view):,} transactions")
    lat = s.units.latency  # every unit's (unitfigures.Latencies: counts per microsecond)
    t = time.perf_counter()
    fig = lat.figures()
    print(f"latency figures, first: {_ms(t):.1f} ms ({fig['lat_n']:,} latencies)")
    lat.add(3.0)
    t = time.perf_counter()
    lat.figures()
    print(f"latency figures after one more value: {_ms(t):.1f} ms")
    mid = len(txs) // 2
    t = time.perf_counter()
    for tx in range(mid, mid + 40):
        format_tx(s, tx)
    print(f"40 lines formatted: {_ms(t):.1f} ms")
    return s


async def tab(s: FrameStore) -> None:
    app = SnifferApp(TuiSink(), None)
    app.store = s
    async with app.run_test(size=(120, 40)) as pilot:
        pane = app.tx_pane
        pane.store = pane.list.store = s
        app.frame_list.store = s
        s.transactions.view_of = None  # as if the tab had never been opened
        t = time.perf_counter()
        await pilot.press("4")
        await pilot.pause()
        print(f"open tab 4: {_ms(t):.0f} ms")
        lat = []
        for key in ("home", "pagedown", "end", "up", "n", "h"):
            t = time.perf_counter()
            await pilot.press(key)
            lat.append(_ms(t))
        print(f"keys in the list (Pilot press incl. its idle wait): median {statistics.median(lat):.0f} ms "
              f"max {max(lat):.0f} ms")
        t = time.perf_counter()
        await pilot.press("enter")
        print(f"Enter -> the request in Frames: {_ms(t):.0f} ms")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=200_000)
    a = ap.parse_args()
    frames = synthetic(a.frames)
    print(f"{len(frames):,} frames")
    s = model(frames)
    asyncio.run(tab(s))


if __name__ == "__main__":
    main()
