"""`sniffer diagnose` against a plain replay of the same capture, measured in the same run.

    .venv/bin/python benchmarks/bench_diagnose.py [--frames N] [--quick] [--keep DIR] [--repeat K]

1. The captures of bench_commands (not timed; `--keep DIR` shares its cache): bench_pipeline's drive mix
   (a PLC's polls with CRC hits, exceptions, lost and late answers and noise) at 115200 8N1 through the
   FTDI read model, N frames and the first quarter of the same traffic (N/4).
2. Each row in a fresh process (bench_commands' child: the clock starts before `sniffer.cli` is imported,
   stdout on /dev/null), on N/4 and on N: `replay --quiet` (decoding alone: the floor), `replay` (text on
   stdout, what a user runs to read a capture), `diagnose` (text) and `diagnose --format json`.
   Each row K times (`--repeat`, default 2), the best (least CPU) run shown: the machine is shared.
3. The engine alone, in this process: the N/4 capture decoded once into memory, then fed to
   `Diagnosis.frame` (best of 3), as microseconds a frame; and `findings()` at the end.
4. The engine in the pipeline, in this process: a capture session read to its end alone (decoding) and
   with `Diagnosis` fed as it passes, then `findings()` (alternately, best of 3 each): the difference is
   what diagnose costs a frame including what it makes the frames build lazily (a decoder's block of
   points becomes dicts when read), which step 3 hides (its frames were built in an earlier pass).
   On the N/4 capture and on each `--also CAPTURE` (e.g. a two-link capture, a fault capture).

Printed: frames/s of each row (by wall time, and by CPU time, which a shared machine disturbs less),
diagnose against `replay --quiet` and against `replay` (the extra CPU time a frame costs), peak RSS
(VmHWM) at N/4 and N, flat memory (N within 10 % of N/4), the target (>= 50,000 frames/s for the command).
Nothing is asserted: tests never assert wall-clock times.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_commands as bc  # noqa: E402 - captures, the measured child, the table
import bench_pipeline as bp  # noqa: E402

TARGET_FPS = 50_000


def rows(folder: Path) -> list[bc.Row]:
    def cap(size: str) -> str:
        return str(folder / f"{'full' if size == 'full' else 'quarter'}.mcap")

    return [
        bc.Row("replay --quiet", "decode only (the floor)", lambda s: ["replay", cap(s), "--quiet"]),
        bc.Row("replay", "replay, text on stdout (/dev/null)", lambda s: ["replay", cap(s)]),
        bc.Row("diagnose", "diagnose, text", lambda s: ["diagnose", cap(s)]),
        bc.Row("diagnose json", "diagnose --format json", lambda s: ["diagnose", cap(s), "--format", "json"]),
    ]


def engine_alone(path: Path) -> dict:
    """Microseconds a frame in Diagnosis.frame alone (frames decoded first, in memory), and findings()."""
    from sniffer.commands.replay import file_source
    from sniffer.diagnose import Diagnosis
    from sniffer.capture.session import CaptureSpec, Session

    spec = CaptureSpec.of(input=str(path), inputs=(str(path),))
    session = Session(spec, file_source(spec), [])
    session.open()
    frames = list(session)
    best, found_s, kinds = float("inf"), 0.0, []
    for _ in range(3):
        d = Diagnosis()
        d.start_session(session)
        t0 = time.process_time()
        for f in frames:
            d.frame(f)
        t1 = time.process_time()
        found = d.findings()
        found_s = time.process_time() - t1
        best = min(best, t1 - t0)
        kinds = [f"{f.kind}{'' if f.unit is None else f':{f.unit}'}" for f in found if f.severity != "info"]
    return {"frames": len(frames), "us_per_frame": best * 1e6 / max(len(frames), 1), "findings_ms": found_s * 1e3,
            "kinds": kinds}


def in_pipeline(path: Path, repeat: int = 3) -> dict:
    """Frames/CPU s of a session read alone and with the engine fed as the frames pass (best of `repeat`)."""
    from sniffer.commands.replay import file_source
    from sniffer.diagnose import Diagnosis
    from sniffer.capture.session import CaptureSpec, Session

    def one(diagnose: bool) -> tuple[float, int]:
        spec = CaptureSpec.of(input=str(path), inputs=(str(path),))
        session = Session(spec, file_source(spec), [])
        session.open()
        n = 0
        t0 = time.process_time()
        if diagnose:
            d = Diagnosis()
            d.start_session(session)
            frame = d.frame
            for f in session:
                frame(f)
                n += 1
            d.findings()
        else:
            for _ in session:
                n += 1
        return time.process_time() - t0, n

    one(True)  # the groups' modules imported, not timed
    alone = both = float("inf")
    n = 0
    for _ in range(repeat):
        a, n = one(False)
        b, n = one(True)
        alone, both = min(alone, a), min(both, b)
    own = max(both - alone, 1e-9)
    return {"frames": n, "decode_fps": n / alone, "both_fps": n / both, "own_us": own * 1e6 / max(n, 1),
            "own_fps": n / own}


def _pipeline_line(name: str, r: dict) -> str:
    return (f"  {name}: {r['frames']:,} frames; decoding {r['decode_fps']:,.0f} frames/CPU s, decoding + diagnose "
            f"{r['both_fps']:,.0f}; diagnose's own {r['own_us']:.1f} us a frame ({r['own_fps']:,.0f} frames/CPU s)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int)
    ap.add_argument("--quick", action="store_true", help="50,000 frames")
    ap.add_argument("--keep", metavar="DIR", help="keep (and reuse) the captures there (bench_commands' cache)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--mem-limit-mb", type=int, default=8192)
    ap.add_argument("--also", metavar="CAPTURE", nargs="*", default=[],
                    help="more captures for the in-pipeline figures (step 4)")
    args = ap.parse_args(argv)
    n = args.frames or (50_000 if args.quick else 400_000)
    now = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    print(f"bench_diagnose {now}: {n:,} frames; {bp.revision()}; load average at start "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    tmp = None
    if args.keep:
        folder = Path(args.keep)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="bench-diagnose-")
        folder = Path(tmp.name)
    try:
        meta = bc.generate(n, folder, "drive")
        meta["_n"] = n
        print(f"captures: scenario {meta['scenario']} at {meta['line']}, {meta['captures']['full']['frames']:,} and "
              f"{meta['captures']['quarter']['frames']:,} frames ({'reused' if meta['cached'] else 'generated'})",
              flush=True)
        out = folder / "out"
        out.mkdir(exist_ok=True)
        got: dict[tuple, dict] = {}
        for row in rows(folder):
            for size in ("quarter", "full"):
                best = None
                for _ in range(max(args.repeat, 1)):
                    res = bc.measure(row, size, folder, out, meta, args.mem_limit_mb)
                    if best is None or (not res["problems"] and res["cpu"] < best["cpu"]):
                        best = res
                got[(row.name, size)] = best
                print(f"  {row.name:<15} {size:<8} {bc._fps(best['frames'], best['wall']):>10,.0f} frames/s  "
                      f"{best['rss_mb']:6.1f} MB  {'; '.join(best['problems']) or 'ok'}", flush=True)
        alone = engine_alone(folder / "quarter.mcap")
        piped = {"N/4 capture": in_pipeline(folder / "quarter.mcap")}
        for extra in args.also:
            piped[extra] = in_pipeline(Path(extra))
    finally:
        if tmp is not None:
            tmp.cleanup()
    print()
    lines = [["row", "frames", "wall s (best)", "frames/s", "CPU s", "frames/CPU s", "vs replay --quiet (CPU)",
              "vs replay (CPU)", "peak RSS N/4 MB", "peak RSS N MB", "flat", f"target >= {TARGET_FPS:,}/s"]]
    for row in rows(Path(".")):
        q, f = got[(row.name, "quarter")], got[(row.name, "full")]
        fps = bc._fps(f["frames"], f["wall"])
        base_q, base = got[("replay --quiet", "full")], got[("replay", "full")]
        flat = f["rss_mb"] <= q["rss_mb"] * (1 + bc.FLAT_TOLERANCE)
        lines.append([row.name, f"{f['frames']:,}", f"{f['wall']:.2f}", f"{fps:,.0f}", f"{f['cpu']:.2f}",
                      f"{bc._fps(f['frames'], f['cpu']):,.0f}",
                      f"{f['cpu'] / base_q['cpu']:.2f}x", f"{f['cpu'] / base['cpu']:.2f}x",
                      bc._mb(q["rss_mb"]), bc._mb(f["rss_mb"]), "yes" if flat else "NO",
                      "ok" if fps >= TARGET_FPS else "BELOW"])
    print("\n".join(bc.table(lines)))
    dq, rq = got[("diagnose", "full")], got[("replay --quiet", "full")]
    extra_us = (dq["cpu"] - rq["cpu"]) * 1e6 / max(dq["frames"], 1)
    print(f"\ndiagnose costs {extra_us:.1f} us of CPU a frame over decoding it (whole command); the engine alone "
          f"{alone['us_per_frame']:.1f} us a frame ({alone['frames']:,} frames in memory, CPU time, best of 3), "
          f"findings() {alone['findings_ms']:.0f} ms; found: {', '.join(alone['kinds']) or 'nothing above info'}")
    print("engine in the pipeline (this process, CPU time, best of 3):")
    for name, r in piped.items():
        print(_pipeline_line(name, r))
    print(f"load average at end {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
