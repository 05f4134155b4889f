"""Per-unit figures (sniffer/analysis/unitfigures.py): what counting costs a frame, and the latency quantiles'
memory, time and error on long streams, against keeping every latency (exact) and semdiff.Quantiles.

    .venv/bin/python benchmarks/bench_unit_figures.py [--frames 200000] [--latencies 1000000]

Frames are bench_tui.synthetic's (decoded frames of errors.mcap and a510.mcap, renumbered).  The
latency streams are log-normal (a bus's latencies: most near the median, a long tail) to the
microsecond, as Frame.latency_ms is.  Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
import time
import tracemalloc
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_tui import synthetic

from sniffer.analysis.diff import Quantiles
from sniffer.analysis.unitfigures import Latencies, UnitBook

QS = (0.5, 0.95, 0.99, 0.999)


def counting(frames) -> None:
    book = UnitBook()
    t = time.perf_counter()
    for f in frames:
        book.frame(f)
    dt = time.perf_counter() - t
    print(f"UnitBook.frame: {1e6 * dt / len(frames):.2f} µs a frame ({len(book)} units, {len(frames):,} frames)")
    t = time.perf_counter()
    book.to_dict()
    print(f"every unit's figures (to_dict, quantiles included): {1e3 * (time.perf_counter() - t):.1f} ms")


def nearest(sorted_values, q: float) -> float:
    return sorted_values[max(1, math.ceil(round(q * len(sorted_values), 9))) - 1]


def stream(name: str, xs: list[float]) -> None:
    exact = sorted(xs)
    print(f"{name}: {len(xs):,} latencies, {len(set(xs)):,} distinct")
    for label, make, add, quantile in (
            ("Latencies (unitfigures)", Latencies, Latencies.add, Latencies.quantile),
            ("semdiff.Quantiles", Quantiles, Quantiles.add, Quantiles.pct),
            ("every value kept (list)", list, list.append, None)):
        t = time.perf_counter()
        q = make()
        for x in xs:
            add(q, x)
        dt = time.perf_counter() - t
        tracemalloc.start()  # the memory of the same stream, again (tracemalloc slows every allocation)
        q = make()
        for x in xs:
            add(q, x)
        size, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        t = time.perf_counter()
        if quantile is None:
            got = [nearest(sorted(q), p) for p in QS]
        else:
            got = [quantile(q, p) for p in QS]
        dq = time.perf_counter() - t
        err = max(abs(g - nearest(exact, p)) / nearest(exact, p) for g, p in zip(got, QS))
        print(f"  {label:26s} add {1e6 * dt / len(xs):5.2f} µs  kept {size / 1e6:6.2f} MB (peak {peak / 1e6:6.2f})"
              f"  quantiles {1e3 * dq:6.1f} ms  worst error vs nearest rank {100 * err:.3f} %")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--latencies", type=int, default=1_000_000)
    a = ap.parse_args()
    counting(synthetic(a.frames))
    rng = random.Random(1)
    stream("a unit answering in ~5 ms", [round(rng.lognormvariate(1.6, 0.3), 3) for _ in range(a.latencies)])
    stream("a slow, spread unit (~20 ms, tail to seconds)",
           [round(rng.lognormvariate(3.0, 1.2), 3) for _ in range(a.latencies)])


if __name__ == "__main__":
    main()
