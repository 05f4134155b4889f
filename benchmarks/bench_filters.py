"""The filter language on a big capture: what the columns answer, the search text, a point's value.

    .venv/bin/python benchmarks/bench_filters.py                       # stress scenario, 200,000 frames
    .venv/bin/python benchmarks/bench_filters.py --scenario a510 --frames 100000
    .venv/bin/python benchmarks/bench_filters.py --capture FILE.mcap "u:2" '"Output frequency" > 50'

1. (not timed) `sniffer simulate --scenario S` long enough for N frames (the rate measured on 10 s),
   or --capture FILE; decoded by the pipeline into a FrameStore as the TUI's replay does, with the
   registry's parameter ids (reg:12-00).
2. Each filter is applied as Enter in the filter bar applies it (FrameStore.update_filter over the
   whole store, from no filter), best of --repeat: milliseconds, rows shown, and how many frames had
   to be rebuilt from their packed blocks (the rest was answered from the columns and the search text).
Figures are printed, nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

FILTERS = {
    "stress": [
        ("columns", "u:2"), ("columns", "u:2 fc:3"), ("columns", "role:rsp !u:1"), ("columns", "t:60s..120s"),
        ("columns", "lat>1ms or err"), ("columns", "reg:300"), ("columns", "reg:0x2100..0x2107 u:3"),
        ("text", "holding[300]"), ("text", "illegal"), ("text", "u:3 0110"),
        ("value", "holding[300] > 100"), ("value", "u:2 holding[300] > 100"), ("value", "8449 >= 3000"),
    ],
    "a510": [
        ("columns", "u:2"), ("columns", "reg:2520H"), ("columns", "fault"), ("columns", "lat>20ms"),
        ("text", '"output current"'), ("text", "OV"),
        ("value", '"Output frequency" > 30'), ("value", 'u:1 "Output frequency" > 30'),
        ("value", '"Error description (fault code)" = OV'), ("value", "2527H >= 10A"),
    ],
}


def simulate(scenario: str, frames: int, folder: Path) -> str:
    from sniffer.cli import main

    probe = str(folder / "probe.mcap")
    main(["simulate", "--scenario", scenario, "--duration", "10", "--out", probe])
    rate = len(load(probe)[0]) / 10
    path = str(folder / f"{scenario}.mcap")
    main(["simulate", "--scenario", scenario, "--duration", f"{frames / rate * 1.01 + 1:.0f}", "--out", path])
    return path


def load(path: str):
    """(FrameStore, seconds) of a capture decoded as `sniffer replay FILE --tui` decodes it."""
    from decoders.registry import default_registry
    from sniffer.filterlang import register_ids
    from sniffer.line import LineSettings
    from sniffer.capture.pipeline import Pipeline
    from sniffer.sources.files import open_replay
    from sniffer.tui.store import FrameStore
    from sniffer.tui.sink import TuiSink

    info, events = open_replay(path)
    registry = default_registry(info.devices)
    sink = TuiSink()
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1), registry, [sink],
                 protocol=info.protocol)
    store = FrameStore(info.t0_ns, ids=register_ids(registry))
    t = time.perf_counter()
    for ev in events:
        p.feed(ev)
        if sink.backlog >= 5000:  # the App's max_batch
            store.add(sink.drain())
    p.finish()
    store.add(sink.drain())
    return store, time.perf_counter() - t


def measure(store, text: str, repeat: int) -> tuple[float, int, int]:
    """(best seconds, rows, frames rebuilt) of one filter applied from no filter."""
    looked = 0
    peek = type(store).peek

    def counting(row):
        nonlocal looked
        looked += 1
        return peek(store, row)

    store.peek = counting
    best = float("inf")
    for _ in range(repeat):
        store.update_filter(units=None, functions=None, roles=None, errors_only=False, text="")
        looked = 0
        t = time.perf_counter()
        store.update_filter(text=text)
        best = min(best, time.perf_counter() - t)
    del store.peek
    return best, len(store.view), looked


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default="stress", choices=sorted(FILTERS))
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--capture", help="an MCAP to load instead of simulating one")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("filters", nargs="*", help="filters to time (default: the scenario's list)")
    a = ap.parse_args()
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(prefix="bench_filters_") as tmp:
        path = a.capture or simulate(a.scenario, a.frames, Path(tmp))
        store, dt = load(path)
    print(f"{path if a.capture else a.scenario}: {len(store):,} frames, decoded into the store in {dt:.1f} s "
          f"(not timed below); packed {store.blocks.packed_bytes / len(store):.0f} B/frame")
    todo = [("", f) for f in a.filters] if a.filters else FILTERS[a.scenario]
    print(f"\n{'kind':8} {'filter':42} {'ms':>9} {'rows':>9} {'frames rebuilt':>15}")
    for kind, text in todo:
        dt, rows, looked = measure(store, text, a.repeat)
        print(f"{kind:8} {text:42} {dt * 1e3:9.1f} {rows:9,} {looked:15,}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} (the machine is shared: wall times move 20-30 %)")


if __name__ == "__main__":
    main()
