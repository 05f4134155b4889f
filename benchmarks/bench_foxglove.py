"""What the Foxglove-native parts of an MCAP cost: `export --to mcap` with them and without, size and speed.

    .venv/bin/python benchmarks/bench_foxglove.py [--frames N] [--quick] [--keep DIR]

1. Captures (not timed), through the sniffer's own session: bench_pipeline's drive mix
   (`drive`: the polls a PLC makes on a generic drive link, 115200 8N1, with errors), the
   `a510` scenario (two TECO A510 drives with their register map, 19200 8N1: what a named
   model adds) and the `stress` scenario (125-register reads at 115200: the most values a frame
   can carry), each with at least N frames.
2. Each row runs `sniffer export CAPTURE --to mcap --out OUT` in a fresh process
   (bench_commands' child: wall, CPU, VmHWM), twice: as the sniffer writes it (the capture and
   the `foxglove` metadata, /annotations, a /values topic per register, the register maps), and
   the peer in the same run, the capture alone (McapSink(foxglove=False): /capture, /raw,
   /frames).  Then `replay OUT --quiet` of each output (a replay reads /raw only: what the
   extra channels cost it).  Not timed: the outputs' sizes and their messages by topic.

Nothing is asserted: tests never assert wall-clock times.
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
import bench_commands as bc  # noqa: E402 - the fresh-process child and its figures
import bench_pipeline as bp  # noqa: E402 - the drive mix, the machine and revision lines

GEN_VERSION = 1


def _session_capture(path: Path, source) -> int:
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.formats import FileSink

    s = Session(CaptureSpec(), source, [FileSink("mcap", path)], keep_partial=True).run()
    if s.error:
        raise SystemExit(f"bench: generating {path.name}: {s.error}")
    return s.frames_out


def generate(n: int, folder: Path) -> dict:
    from sniffer.simulator import get_scenario
    from sniffer.simulator.sources import SimulatedSource

    meta_path = folder / "meta.json"
    want = {"version": GEN_VERSION, "frames_asked": n}
    if meta_path.exists():
        meta = json.loads(meta_path.read_text())
        if {k: meta.get(k) for k in want} == want and all((folder / f"{k}.mcap").exists() for k in meta["captures"]):
            return meta
    folder.mkdir(parents=True, exist_ok=True)
    caps = {}
    for name, scenario in (("drive", bp.bench_scenario()), ("a510", get_scenario("a510")),
                           ("stress", get_scenario("stress"))):
        line = bp.LINE if name == "drive" else scenario.line
        rate = bc._frame_rate(scenario) if name != "a510" else _rate(scenario, line)
        duration = n / rate * 1.02 + 1.0
        frames = _session_capture(folder / f"{name}.mcap", SimulatedSource(scenario, line, duration, bp.SEED, "usb"))
        caps[name] = {"frames": frames, "line": line.label(), "scenario": scenario.name}
    meta = {**want, "captures": caps, "generated_with": bp.revision()}
    meta_path.write_text(json.dumps(meta, indent=1))
    return meta


def _rate(scenario, line) -> float:
    from sniffer.simulator import KIND_NOISE, simulate

    return sum(1 for f in simulate(scenario, line, 20.0, bp.SEED) if f.kind != KIND_NOISE) / 20.0


def child(result: Path, plain: bool, argv: list[str]) -> int:
    if plain:  # the peer: the same export, the capture alone
        from sniffer.formats.mcap import sink as mcap

        init = mcap.McapSink.__init__

        def plain_init(self, path, **kw):
            init(self, path, **{**kw, "foxglove": False})

        mcap.McapSink.__init__ = plain_init
    return bc.child_run(result, argv, 0)


def measured(argv: list[str], plain: bool) -> dict:
    with tempfile.TemporaryDirectory() as d:
        res = Path(d) / "r.json"
        cmd = [sys.executable, __file__, "--child", str(res), "--plain" if plain else "--fox", "--", *argv]
        p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if p.returncode != 0 or not res.exists():
            raise SystemExit(f"bench: {' '.join(argv)} failed: {p.stderr.strip()[-400:]}")
        out = json.loads(res.read_text())
    if out["rc"] != 0:
        raise SystemExit(f"bench: {' '.join(argv)} exit {out['rc']}: {out['error']}")
    return out


def contents(path: Path) -> dict:
    """Messages by kind of topic, channels, attachment bytes (read from the summary)."""
    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        s = reader.get_summary()
        att = sum(len(a.data) for a in reader.iter_attachments())
    kinds: dict[str, int] = {}
    for cid, n in s.statistics.channel_message_counts.items():
        topic = s.channels[cid].topic
        kind = "/values" if topic.startswith("/values/") else topic
        kinds[kind] = kinds.get(kind, 0) + n
    return {"messages": kinds, "channels": len(s.channels), "attachments": att}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000)
    ap.add_argument("--quick", action="store_true", help="20,000 frames")
    ap.add_argument("--keep", metavar="DIR", help="keep the captures there (reused by the next run)")
    ap.add_argument("--child", metavar="RESULT", help=argparse.SUPPRESS)
    ap.add_argument("--plain", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--fox", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("rest", nargs="*", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        return child(Path(a.child), a.plain, a.rest)
    n = 20_000 if a.quick else a.frames
    tmp = None
    if a.keep:
        folder = Path(a.keep)
    else:
        tmp = tempfile.TemporaryDirectory()
        folder = Path(tmp.name)
    t0 = time.perf_counter()
    meta = generate(n, folder)
    print(f"captures in {folder} ({time.perf_counter() - t0:.0f} s; generated with {meta['generated_with']})")
    head = (f"{'capture':<8} {'writer':<10} {'frames':>9} {'export s':>9} {'CPU s':>7} {'frames/s':>9} "
            f"{'peak MB':>8} {'file MB':>8} {'B/frame':>8} {'replay s':>9}  messages (channels)")
    print(head)
    print("-" * len(head))
    for name, cap in meta["captures"].items():
        src = folder / f"{name}.mcap"
        got = {}
        for plain in (True, False):
            out = folder / f"{name}.{'plain' if plain else 'foxglove'}.out.mcap"
            r = measured(["export", str(src), "--to", "mcap", "--out", str(out)], plain)
            rp = measured(["replay", str(out), "--quiet"], plain)
            size = os.path.getsize(out)
            c = contents(out)
            frames = cap["frames"]
            got[plain] = (r, size)
            msgs = ", ".join(f"{k} {v:,}" for k, v in sorted(c["messages"].items()) if k != "/capture")
            extra = f"; maps {c['attachments'] / 1e3:.0f} kB" if c["attachments"] else ""
            print(f"{name:<8} {'capture' if plain else 'foxglove':<10} {frames:>9,} {r['wall']:>9.2f} {r['cpu']:>7.2f} "
                  f"{frames / r['wall']:>9,.0f} {r['rss_mb']:>8.1f} {size / 1e6:>8.2f} {size / frames:>8.1f} "
                  f"{rp['wall']:>9.2f}  {msgs} ({c['channels']}){extra}")
        (rp_, sp), (rf, sf) = got[True], got[False]
        print(f"{'':<8} {'foxglove/capture':<20} size x{sf / sp:.2f}, export CPU x{rf['cpu'] / rp_['cpu']:.2f}, "
              f"peak RSS {rf['rss_mb'] - rp_['rss_mb']:+.1f} MB")
    print(f"machine: {bp.machine()}; revision {bp.revision()}")
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
