"""How long `sniffer detect` takes to settle a line, per scenario (issue 12: a line polled at >= 5 Hz in < 10 s).

    .venv/bin/python benchmarks/bench_detect.py [--repeat 3] [--only default,tds-v8]

Each line is served by `sniffer simulate --pty LINK --scenario S --baud B --parity P --stopbits N
[--param poll_period_ms=200]` (a UART model on a pseudo-terminal: what the settings detect tries would
receive), and `sniffer detect LINK -q --units-time 0` runs against it, as a user runs both.  Printed per
line: the verdict, the listening time to it (detect's own "settled in" figure, from the port opened to the
verdict) and the command's wall time (interpreter start included), the number of settings tried; min /
median / max over the repeats.  The lines are placed early and late in detect's order of rates (9600 and
19200 first, 921600 last, 1200 among the last).  Also, on the virtual-clock port
(simulator/simport.py, no pty, no waiting), the same lines with a UART that resynchronises 16550-style
after a framing error (garbling an 11-bit line read at 8N1: found by the second sweep, at 8E1).
Nothing is asserted: tests never assert wall-clock times.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

# (scenario, baud, format, extra simulate args): lines polled at 5 Hz or more
LINES = [
    ("default", 19200, "8E1", []),  # 10 Hz cycles, 3 units
    ("tds-v8", 9600, "8N2", []),  # 5 Hz: 8N2, told from 8N1 by timing
    ("a510", 19200, "8N1", []),
    ("fast", 115200, "8N1", []),  # back to back, never silent for t3.5
    ("a510-ascii", 9600, "7E1", ["--param", "poll_period_ms=200"]),
    ("pd-series", 9600, "8N1", ["--param", "poll_period_ms=200"]),
    ("default", 38400, "8O1", ["--param", "poll_period_ms=200"]),
    ("default", 1200, "8E1", []),  # among the last rates tried
    ("default", 921600, "8O1", ["--param", "poll_period_ms=200"]),  # the last rate tried
]


def sniffer(*args) -> list[str]:
    return [sys.executable, "-m", "sniffer", *args]


def run_line(scenario: str, baud: int, fmt: str, extra: list[str], folder: str) -> dict:
    link = os.path.join(folder, f"line-{scenario}-{baud}")
    sim = subprocess.Popen(sniffer("simulate", "--pty", link, "--scenario", scenario, "--baud", str(baud),
                                   "--parity", fmt[1], "--stopbits", fmt[2], *extra),
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while not os.path.lexists(link) and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)  # the line has been talking for a while when the engineer plugs in
        t0 = time.monotonic()
        r = subprocess.run(sniffer("detect", link, "-q", "--units-time", "0"), capture_output=True, text=True)
        wall = time.monotonic() - t0
    finally:
        sim.terminate()
        sim.communicate(timeout=30)
    m = re.search(r"^line: (\S+ \S+ \S+) \((.*)$", r.stdout, re.M)
    settled = re.search(r"settled in ([\d.]+) s of listening \((\d+) settings\)", r.stdout)
    return {"rc": r.returncode, "found": m.group(1) if m else r.stderr.strip()[:80],
            "how": _how(m.group(2)) if m else "-", "listen": float(settled.group(1)) if settled else None,
            "tried": int(settled.group(2)) if settled else None, "wall": wall}


def _how(text: str) -> str:
    if text.startswith("certain:"):
        return "certain"
    return "1 or 2 stop bits" if "stop bits not told apart" in text else "fits"


def spread(xs) -> str:
    xs = [x for x in xs if x is not None]
    if not xs:
        return "-"
    return f"{min(xs):5.1f} {statistics.median(xs):5.1f} {max(xs):5.1f}"


def virtual_clock(lines) -> None:
    from sniffer.detect.candidates import COMMON_BAUDS, setting
    from sniffer.detect.listen import listen
    from sniffer.detect.search import Search
    from sniffer.simulator import get_scenario
    from sniffer.simulator.overrides import apply
    from sniffer.simulator.simport import SimulatedPort

    print("\nvirtual clock (no pty), a UART that resynchronises 16550-style; start at 0.1 / 0.5 / 1.3 / 3.7 s:")
    print(f"  {'line':28} {'verdict':44} listening s (min med max)")
    for scenario, baud, fmt, extra in lines:
        sc = apply(get_scenario(scenario), extra[1::2] or None)
        got, secs = set(), []
        for start in (0.1, 0.5, 1.3, 3.7):
            v = listen(SimulatedPort(sc, setting(baud, fmt), resync="16550", start_s=start), Search(COMMON_BAUDS))
            got.add(f"{v.best.rx.baud} {v.best.fmt} {v.status}" if v.best else v.status)
            secs.append(v.decided_s)
        print(f"  {scenario + ' ' + str(baud) + ' ' + fmt:28} {', '.join(sorted(got)):44} {spread(secs)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", help="scenarios, comma-separated")
    args = ap.parse_args()
    lines = [x for x in LINES if not args.only or x[0] in args.only.split(",")]
    print(f"sniffer detect on pty lines, {args.repeat} runs each (load average {os.getloadavg()[0]:.1f})")
    print(f"  {'line':28} {'found':44} {'listening s':17} {'wall s':17} settings")
    with tempfile.TemporaryDirectory() as folder:
        for scenario, baud, fmt, extra in lines:
            runs = [run_line(scenario, baud, fmt, extra, folder) for _ in range(args.repeat)]
            found = ", ".join(sorted({f"{r['found']} ({r['how']})" for r in runs}))
            tried = sorted({r["tried"] for r in runs if r["tried"]})
            name = f"{scenario} {baud} {fmt}" + (" @5 Hz" if extra else "")
            print(f"  {name:28} {found:44} {spread(r['listen'] for r in runs):17} "
                  f"{spread(r['wall'] for r in runs):17} {'/'.join(map(str, tried))}")
    print("  (listening s, wall s: min median max)")
    virtual_clock(lines)


if __name__ == "__main__":
    main()
