"""Several links on one timeline (issue 12): three simulated links at 115200 baud running the stress
scenario for 60 s on pseudo-terminals, captured by one `sniffer live P1 P2 P3`; a single-link capture of
the same line in the same run is the peer.

    .venv/bin/python benchmarks/bench_links.py [--seconds 60] [--links 3]

The lines are played from this process (one PtyBus and thread per link, every frame at its bus time);
`sniffer live ... --headless --quiet --out X.mcap` runs as a user runs it, in a process of its own, its
CPU time and peak RSS taken from wait4().  Printed per run and link: the bytes sent, the bytes in the
MCAP's /raw events of that link (every byte captured: nothing lost), the frames decoded and how many
had a bad CRC or were noise (bytes of one link glued onto another's would show there); then the
capture's CPU (user + system, as a share of one CPU over the capture's wall time) and peak RSS.
Nothing is asserted: tests never assert wall-clock times.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from sniffer.events import Chunk  # noqa: E402
from sniffer.simulator.bus import simulate  # noqa: E402
from sniffer.simulator.ptybus import PtyBus  # noqa: E402
from sniffer.simulator.scenario import get_scenario  # noqa: E402
from sniffer.formats.mcap.reader import open_mcap, read_frames  # noqa: E402

SETTLE_S = 2.0  # after the last frame: the capture sees the lines go quiet before --duration ends it


def _peak_rss_watch(pid: int, stop: threading.Event) -> list[int]:
    """[kB]: the capture's peak RSS (VmHWM), read every 0.2 s until it exits.  Not wait4's ru_maxrss:
    that counts the forked copy of this process before it became the capture."""
    hwm = [0]

    def watch():
        while True:
            try:
                with open(f"/proc/{pid}/status") as f:
                    for line in f:
                        if line.startswith("VmHWM:"):
                            hwm[0] = max(hwm[0], int(line.split()[1]))
            except OSError:
                return
            time.sleep(0.2)

    threading.Thread(target=watch, daemon=True).start()
    return hwm


def run(n_links: int, seconds: float, folder: str) -> dict:
    sc = get_scenario("stress")
    sent = [list(simulate(sc, sc.line, seconds, seed=i + 1)) for i in range(n_links)]
    buses = [PtyBus() for _ in range(n_links)]
    out = os.path.join(folder, f"links{n_links}.mcap")
    names = [os.path.basename(b.port) for b in buses]
    try:
        argv = [sys.executable, "-m", "sniffer", "live", *[b.port for b in buses], "--baud", str(sc.line.baud),
                "--duration", str(seconds + 2 * SETTLE_S), "--headless", "--quiet", "--out", out]
        proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
        first = proc.stderr.readline()  # "capturing ...": every port is open, the lines may talk
        t0 = time.monotonic()
        stop = threading.Event()
        players = [threading.Thread(target=b.play, args=(s, 1.0, stop), daemon=True) for b, s in zip(buses, sent)]
        for p in players:
            p.start()
        hwm = _peak_rss_watch(proc.pid, stop)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.monotonic() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        rest = proc.stderr.read()
        stop.set()
        for p in players:
            p.join()
        back = sum(b.bytes_received_from_sniffer for b in buses)
    finally:
        for b in buses:
            b.close()
    if proc.returncode != 0:
        raise SystemExit(f"capture failed ({proc.returncode}): {first}{rest}")
    info, events = open_mcap(out)
    got = Counter()
    for ev in events:
        if type(ev) is Chunk:
            got[ev.link] += len(ev.data)
    frames = read_frames(out)
    per = {}
    for i, s in enumerate(sent):
        name = names[i] if n_links > 1 else ""
        mine = [f for f in frames if f.get("link", "") == name]
        per[names[i]] = {"sent": sum(len(f.raw) for f in s), "captured": got[name], "frames": len(mine),
                         "sent_frames": len(s), "crc_bad": sum(f["crc_ok"] is False for f in mine),
                         "noise": sum(f["protocol"] == "noise" for f in mine)}
    return {"links": per, "cpu_s": usage.ru_utime + usage.ru_stime, "wall_s": wall,
            "rss_mb": hwm[0] / 1024, "written_back": back, "mcap_mb": os.path.getsize(out) / 1e6}


def report(title: str, r: dict) -> None:
    print(f"\n{title}: capture CPU {r['cpu_s']:.1f} s in {r['wall_s']:.1f} s ({100 * r['cpu_s'] / r['wall_s']:.1f} % "
          f"of one CPU), peak RSS {r['rss_mb']:.0f} MB, MCAP {r['mcap_mb']:.1f} MB, "
          f"{r['written_back']} bytes written to the ports")
    print(f"  {'link':<10} {'bytes sent':>11} {'captured':>11} {'lost':>6} {'frames sent':>12} {'decoded':>8} "
          f"{'CRC bad':>8} {'noise':>6}")
    for name, x in r["links"].items():
        print(f"  {name:<10} {x['sent']:>11,} {x['captured']:>11,} {x['sent'] - x['captured']:>6,} "
              f"{x['sent_frames']:>12,} {x['frames']:>8,} {x['crc_bad']:>8} {x['noise']:>6}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="seconds of traffic per run (default 60)")
    ap.add_argument("--links", type=int, default=3, help="links in the multi-link run (default 3)")
    args = ap.parse_args()
    print(f"stress scenario at 115200 8N1, {args.seconds:g} s of traffic per link, {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as folder:
        multi = run(args.links, args.seconds, folder)
        single = run(1, args.seconds, folder)
    report(f"{args.links} links, one `sniffer live P1 .. P{args.links}`", multi)
    report("1 link, `sniffer live P1` (the peer)", single)


if __name__ == "__main__":
    main()
