"""The fleet dataset on one core: `sniffer ingest` of 10 M frames, its size, and queries (DuckDB vs peers).

    .venv/bin/python benchmarks/bench_dataset.py [--frames 10000000] [--segments 10] [--keep DIR] [--cpu N]

1. Generate (not timed): one simulated capture of frames/segments frames (bench_pipeline's
   drive-link scenario at 115200 8N1 through the FTDI read model, bench_commands' generator),
   then `segments` copies of its events as separate MCAP files, each with a wall clock one
   day after the previous one's (the same traffic as segments of a longer capture, on
   consecutive dates; different content, so the dataset takes each in).  `--keep DIR`
   keeps and reuses them.
2. Pin the whole run to one CPU (`--cpu`, default the last), then run `sniffer ingest
   SEGMENTS --to DATASET` in a fresh process (bench_commands' `--run` child: wall, CPU,
   peak RSS): frames/s, dataset bytes per frame (beside the MCAP's), peak RSS; then the same
   command again (everything already there: the incremental check's cost); one segment alone
   (peak RSS: flat in the number of segments) and the same segment by `export --to parquet`
   (the Parquet export the dataset builds on, as a peer).
3. Queries on the dataset, best of 3, in this process with DuckDB at one thread: the
   `faults` preset (problems by link, unit and code), `latency` and a plain count of bad-CRC
   frames; the peers on the same files: pyarrow.dataset (a filter and a group-by in Arrow's
   C++) and pandas (read_parquet of the columns needed, then groupby).  Each result is checked
   against DuckDB's.

When --frames is below 10 M the figures are also extrapolated to 10 M (frames/s and bytes per
frame do not depend on the total; query times scale with the rows), labelled as such, with the
command of the full run.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_commands as bc  # noqa: E402 - the generator, the measured child run
import bench_pipeline as bp  # noqa: E402 - the scenario and machine lines

DAY_NS = 86_400 * 10**9
BASE_WALL_NS = 1_790_000_000 * 10**9  # 2026-09-21, 14:13 UTC: the first segment's wall clock
GEN_VERSION = 1


def generate(n: int, segments: int, folder: Path) -> dict:
    want = {"version": GEN_VERSION, "frames": n, "segments": segments, "seed": bp.SEED}
    meta_path = folder / "meta.json"
    if meta_path.exists():
        meta = json.loads(meta_path.read_text())
        if {k: meta.get(k) for k in want} == want:
            meta["cached"] = True
            return meta
    shutil.rmtree(folder, ignore_errors=True)
    (folder / "segments").mkdir(parents=True)
    t0 = time.perf_counter()
    per = n // segments
    rate = bc._frame_rate(bp.bench_scenario())
    base = bc._simulate_to(folder, "base", per / rate * 1.02 + 1.0, bp.SEED)
    (folder / "base.csv").unlink()
    for k in range(segments):
        _copy_with_clock(folder / "base.mcap", folder / "segments" / f"line1-{k:03d}.mcap", BASE_WALL_NS + k * DAY_NS)
    meta = {**want, "frames_per_segment": base["frames"], "total_frames": base["frames"] * segments,
            "mcap_bytes": sum(p.stat().st_size for p in (folder / "segments").iterdir()),
            "gen_s": round(time.perf_counter() - t0, 1), "cached": False}
    meta_path.write_text(json.dumps(meta, indent=1))
    return meta


def _copy_with_clock(src: Path, dst: Path, wall_ns: int) -> None:
    """The capture's events into a new MCAP whose wall clock starts at `wall_ns` (raw only: replay decodes)."""
    from sniffer.formats.mcap.sink import McapSink
    from sniffer.sources.files import FileSource

    source = FileSource(str(src))
    info = source.open()
    info.wall_anchor_ns = wall_ns
    info.port = "/dev/ttyUSB1"
    sink = McapSink(str(dst))
    sink.start(info)
    for ev in source.events():
        sink.raw(ev)
    sink.close()
    source.close()


def du(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def best_of(fn, k: int = 3) -> tuple[float, object]:
    times, out = [], None
    for _ in range(k):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


ERROR_OR = ("modbus.exception", "model.exception.vendor", "model.fault", "model.alarm", "pair.timeout",
            "pair.no_response", "source.gap")


def queries(ds: Path) -> list[tuple[str, str, float, str]]:
    """(query, engine, best seconds, result summary) for DuckDB and the peers, results cross-checked."""
    import pandas as pd
    import pyarrow.compute as pc
    import pyarrow.dataset as pads

    from sniffer.dataset.layout import open_dataset
    from sniffer.dataset.query import PRESETS, connect

    con = connect(open_dataset(str(ds)), threads=1)
    out = []

    def duck(sql):
        return con.execute(sql).fetchall()

    t, faults = best_of(lambda: duck(PRESETS["faults"].sql))
    want = {(r[0], r[1], r[2]): r[4] for r in faults}
    out.append(("faults preset", "DuckDB", t, f"{len(faults)} groups, {sum(want.values()):,} annotations"))

    part = pads.partitioning(flavor="hive")

    def arrow_faults():
        d = pads.dataset(str(ds / "annotations"), format="parquet", partitioning=part)
        flt = (pc.field("severity") == "error") | pc.field("code").isin(list(ERROR_OR))
        tbl = d.to_table(columns=["link", "unit", "code", "severity"], filter=flt)
        g = tbl.group_by(["link", "unit", "code"]).aggregate([("severity", "count")])
        return {(str(a), b, c): n for a, b, c, n in zip(*(g.column(x).to_pylist()
                                                          for x in ("link", "unit", "code", "severity_count")))}

    t, got = best_of(arrow_faults)
    out.append(("faults preset", "pyarrow.dataset", t, "same as DuckDB" if got == want else "DIFFERENT"))

    def pandas_faults():
        df = pd.read_parquet(ds / "annotations", columns=["link", "unit", "code", "severity"])
        df = df[(df.severity == "error") | df.code.isin(ERROR_OR)]
        g = df.groupby(["link", "unit", "code"], observed=True, dropna=False).size()
        return {(str(a), None if pd.isna(b) else int(b), c): int(n) for (a, b, c), n in g.items()}

    t, got = best_of(pandas_faults)
    out.append(("faults preset", "pandas", t, "same as DuckDB" if got == want else "DIFFERENT"))

    t, lat = best_of(lambda: duck(PRESETS["latency"].sql))
    out.append(("latency preset", "DuckDB", t, f"{len(lat)} units, {sum(r[2] for r in lat):,} responses"))
    t, (n_bad,) = best_of(lambda: duck("SELECT count(*) FROM frames WHERE NOT crc_ok")[0])
    out.append(("bad-CRC frames", "DuckDB", t, f"{n_bad:,}"))

    def arrow_bad():
        d = pads.dataset(str(ds / "frames"), format="parquet", partitioning=part)
        return d.count_rows(filter=pc.field("crc_ok") == False)  # noqa: E712 - an Arrow expression

    t, got = best_of(arrow_bad)
    out.append(("bad-CRC frames", "pyarrow.dataset", t, "same as DuckDB" if got == n_bad else f"DIFFERENT {got}"))
    con.close()
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10_000_000)
    ap.add_argument("--segments", type=int, default=10)
    ap.add_argument("--keep", metavar="DIR", help="keep the generated captures there (and reuse them)")
    ap.add_argument("--cpu", type=int, default=(os.cpu_count() or 1) - 1, help="the CPU to run on")
    args = ap.parse_args(argv)
    os.sched_setaffinity(0, {args.cpu})  # children inherit it: one core for everything
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-dataset-"))
    try:
        print(f"{bp.machine()}; {bp.revision()}; pinned to CPU {args.cpu}; load {os.getloadavg()[0]:.2f}")
        meta = generate(args.frames, args.segments, work / "captures")
        frames = meta["total_frames"]
        print(f"captures: {args.segments} segments of {meta['frames_per_segment']:,} frames = {frames:,} frames, "
              f"MCAP {meta['mcap_bytes'] / 1e6:.1f} MB ({meta['mcap_bytes'] / frames:.1f} B/frame)"
              f"{' (cached)' if meta.get('cached') else ', generated in %s s' % meta['gen_s']}")
        ds = work / "dataset"
        shutil.rmtree(ds, ignore_errors=True)
        argv_ingest = ["ingest", str(work / "captures" / "segments"), "--to", str(ds)]
        res = bc.run_measured(argv_ingest, 0)
        if res.get("rc") != 0:
            print(f"ingest FAILED: {res.get('error')} {res.get('stderr', '')[-500:]}")
            return 1
        size = du(ds)
        fps = frames / res["wall"]
        again = bc.run_measured(argv_ingest, 0)
        first = sorted((work / "captures" / "segments").iterdir())[0]
        one_ds = work / "one-segment"
        shutil.rmtree(one_ds, ignore_errors=True)
        one = bc.run_measured(["export", str(first), "--to", "dataset", str(one_ds)], 0)
        shutil.rmtree(one_ds, ignore_errors=True)
        peer = bc.run_measured(["export", str(first), "--to", "parquet", "--out", str(work / "peer.parquet")], 0)
        for p in work.glob("peer*.parquet"):
            p.unlink()
        rows = [
            ["ingest (decode + write), frames/s", f"{fps / 1e3:,.1f}k",
             f"{res['wall']:.1f} s wall, {res['cpu']:.1f} s CPU"],
            ["peak RSS of the ingest", f"{res['rss_mb']:.0f} MB",
             f"one segment alone: {one['rss_mb']:.0f} MB (export --to dataset); the same segment by "
             f"export --to parquet: {peer['rss_mb']:.0f} MB, {meta['frames_per_segment'] / peer['wall'] / 1e3:.1f}k "
             f"frames/s"],
            ["dataset size", f"{size / 1e6:,.1f} MB",
             f"{size / frames:.1f} B/frame (MCAP {meta['mcap_bytes'] / frames:.1f})"],
            ["ingest again (all known)", f"{again['wall']:.2f} s",
             f"rc {again.get('rc')}: size+mtime check, nothing read"],
        ]
        for name, engine, t, what in queries(ds):
            rows.append([f"{name}: {engine}", f"{t * 1e3:,.0f} ms", what])
        width = max(len(r[0]) for r in rows)
        for r in rows:
            print(f"{r[0]:<{width}}  {r[1]:>10}  {r[2]}")
        if frames < 10_000_000:
            k = 10_000_000 / frames
            print(f"\nEXTRAPOLATED to 10 M frames (measured {frames:,}; x{k:.1f}; not a measurement):")
            print(f"  ingest {10_000_000 / fps:,.0f} s at {fps / 1e3:,.1f}k frames/s; dataset {size * k / 1e9:.2f} GB "
                  f"({size / frames:.1f} B/frame); queries about x{k:.0f} the times above")
            print("  the full run: .venv/bin/python benchmarks/bench_dataset.py --frames 10000000 --segments 10")
        return 0
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
