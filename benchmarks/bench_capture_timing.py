"""Does anything spoil a live capture's timing?  The TUI open or not, and the reader's interpreter wait.

    .venv/bin/python benchmarks/bench_capture_timing.py [--scenario stress] [--seconds 20] [--repeat 2]

A simulated line (PtyBus) is played from a feeder process of its own onto a pty; `sniffer live` reads the
other end, exactly as it reads an adapter, in these configurations (each `--repeat` times, interleaved so
the machine's load falls on all alike):

* headless            `sniffer live PORT --headless --out F.mcap` (the port read by a process of its own:
                      processes/reader.py)
* tui                 `sniffer live PORT --out F.mcap` on a terminal (a pty): the TUI attached to the
                      capture process it started, at nice 19, giving way (sniffer/processes/cpu_yield.py)
* headless-thread     the peer: headless, the port read by a thread of the capture's process
                      (SNIFFER_READER=thread), as before the reader process
* tui-thread          the same for the TUI's capture
* tui-no-give-way     the TUI without giving way (as before it, nice 19 kept)
* headless-5ms        the capture as before issue 11, its reader thread waiting up to CPython's default
                      switch interval for the interpreter (READER_SWITCH_S patched back to 5 ms)

and, with --kinds, where a TUI's harm comes from:

* publish             headless, publishing on a socket nobody attaches to
* attached            headless, publishing, a text viewer (`sniffer attach SOCK`) taking every frame
* attached3           the same with three such viewers
* attached-idle       the same viewer under SCHED_IDLE (`chrt -i 0`)
* burst               headless, and a plain process at nice 19 busy 1.3 ms every 10 ms (a redraw's pattern)
* burst-yield         the same process with the TUI's give-way: SIGALRM every 0.2 ms, handled by sched_yield
* burst28-yield       the same, busy 2.8 ms every 10 ms (as much CPU as the TUI under live stress)
* tui-no-output       the TUI drawing as ever, what it draws thrown away instead of written to its terminal
* KIND-peer           any kind, run by the sniffer of the tree given with --peer DIR (a worktree of an older
                      commit): a change measured against its before in the same rounds

For each: responses, responses with no latency (their request came in the same read: glued), split into
"line" (the feeder wrote request and answer less than LINE_GLUED_MS apart: the simulated line itself was
late, the capture could not tell them apart) and "capture" (the capture's reads came late); responses timed
before their request ended, and the read lateness (time of the read holding a frame's last byte minus the
end of the feeder's write; both the host's monotonic clock) p50 / p90 / p99 / max.  Also the load average,
and the capture's CPU seconds (its process's threads and its reader process; not the publisher process).

The feeder runs SCHED_FIFO where permitted (--feeder normal: not): a real PLC and drive are not delayed by
this machine's load, a feeder process at the normal policy is, and a late feeder writes a request and its
answer together (before --feeder existed, a TUI's CPU counted twice: it delayed the feeder too).  Figures
are printed, nothing asserted.
"""

from __future__ import annotations

import argparse
import bisect
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from terminal import Terminal

from sniffer.events import Chunk
from sniffer.formats.mcap.reader import open_mcap, read_frames

FEEDER = r"""
import json, os, sys, time
from sniffer.simulator.bus import simulate
from sniffer.simulator.ptybus import PtyBus
from sniffer.simulator.scenario import get_scenario
sc = get_scenario(sys.argv[1])
if sys.argv[5]:  # --turnaround-ms: every unit answers that long after its request
    import dataclasses
    char_ms = 1000 * (1 + sc.line.databits + (sc.line.parity != "N") + sc.line.stopbits) / sc.line.baud
    lo, hi = (float(x) / char_ms for x in sys.argv[5].split(","))
    sc = dataclasses.replace(sc, units=tuple(dataclasses.replace(u, turnaround_chars=(lo, hi)) for u in sc.units))
frames = list(simulate(sc, sc.line, float(sys.argv[2]), 3))
policy = "normal"
if sys.argv[4] == "fifo":  # the line is hardware: nothing on this machine delays a real PLC or drive
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        policy = "SCHED_FIFO"
    except (AttributeError, OSError):
        pass
times = []
class Timed(PtyBus):
    def write_all(self, data, stop_event):
        before = time.monotonic_ns()
        ok = super().write_all(data, stop_event)
        times.append((before, time.monotonic_ns()))
        return ok
with Timed() as bus:
    print(bus.port, sc.line.baud, sc.line.parity, sc.line.stopbits, policy, flush=True)
    sys.stdin.readline()
    bus.play(frames)
    time.sleep(0.5)
    json.dump(times, open(sys.argv[3], "w"))
    print("done", bus.bytes_received_from_sniffer, flush=True)
    sys.stdin.readline()
"""

OLD_SWITCH = ("import sys, sniffer.sources.serial_live as s; s.READER_SWITCH_S = 0.005; "
              "from sniffer.cli import main; sys.argv[0] = 'sniffer'; sys.exit(main())")
LINE_GLUED_MS = 0.1  # a request and its answer written closer than this: the feeder's own lateness glued them
NO_GIVE_WAY = ("import sys, sniffer.processes.cpu_yield as g; g._LIBC = g._SCHED_YIELD = None; "
               "from sniffer.cli import main; sys.argv[0] = 'sniffer'; sys.exit(main())")
# the TUI giving way every 0.1 ms, not every GIVE_WAY_S (0.2 ms)
FAST_GIVE_WAY = ("import sys, sniffer.processes.cpu_yield as g; g.GiveWay.__init__.__defaults__ = (0.0001,); "
                 "from sniffer.cli import main; sys.argv[0] = 'sniffer'; sys.exit(main())")
# the peer: the port read by a thread of the capture's own process, as before processes/reader.py
THREAD_READER = ["env", "SNIFFER_READER=thread", sys.executable, "-m", "sniffer"]
# the TUI drawing as ever, its output thrown away once drawn (not written to the terminal)
NO_OUTPUT = ("import sys, textual.drivers.linux_driver as d; d.LinuxDriver.write = lambda self, data: None; "
             "from sniffer.cli import main; sys.argv[0] = 'sniffer'; sys.exit(main())")
# a process busy 1.3 ms every 10 ms at nice 19 (13 % of a core, in bursts like a redraw's); with "yield", its
# SIGALRM every 0.2 ms handled by sched_yield, as the TUI's give-way does (sniffer/processes/cpu_yield.py)
BURST = r"""
import os, signal, sys, time
os.nice(19)
if sys.argv[1] == "yield":
    from sniffer.processes.cpu_yield import GiveWay
    GiveWay(lambda: time.monotonic_ns()).start()
end = time.monotonic() + float(sys.argv[2])
while time.monotonic() < end:
    t = time.monotonic()
    while time.monotonic() - t < float(sys.argv[3]):
        pass
    time.sleep(0.01 - float(sys.argv[3]))
"""


def run_one(kind: str, scenario: str, seconds: float, work: Path, feeder_policy: str = "fifo",
            turnaround_ms: str = "", peer: str = "") -> dict:
    times_path, out = work / f"{kind}.times.json", work / f"{kind}.mcap"
    for p in (times_path, out):
        p.unlink(missing_ok=True)
    feeder = subprocess.Popen([sys.executable, "-c", FEEDER, scenario, str(seconds), str(times_path), feeder_policy,
                               turnaround_ms],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    port, baud, parity, stop, policy = feeder.stdout.readline().split()
    label, kind = kind, kind.removesuffix("-peer")  # -peer: the same run, the sniffer of another tree (--peer)
    head = {"headless-5ms": ["env", "SNIFFER_READER=thread", sys.executable, "-c", OLD_SWITCH],
            "tui-no-give-way": [sys.executable, "-c", NO_GIVE_WAY],
            "tui-no-output": [sys.executable, "-c", NO_OUTPUT],
            "tui-100us": [sys.executable, "-c", FAST_GIVE_WAY],
            }.get(kind, THREAD_READER if kind.endswith("-thread") else [sys.executable, "-m", "sniffer"])
    if label != kind:
        head = ["env", f"PYTHONPATH={peer}", *(head[1:] if head[0] == "env" else head)]
    kind_as = kind.removesuffix("-thread")  # the same run, its port read by a thread of the capture
    argv = [*head, "live", port, "--baud", baud, "--parity", parity, "--stopbits", stop, "--out", str(out)]
    sock = str(work / f"{kind}.sock")
    extra = {"tui": [], "tui-no-give-way": [], "tui-no-output": [], "tui-100us": [],
             "publish": ["--headless", "--quiet", "--publish", sock],
             "attached": ["--headless", "--quiet", "--publish", sock],
             "attached3": ["--headless", "--quiet", "--publish", sock],
             "attached-idle": ["--headless", "--quiet", "--publish", sock]}.get(kind_as, ["--headless", "--quiet"])
    term = Terminal(argv + extra)
    viewers = []
    cpu0 = os.times()
    try:
        if kind_as == "tui-no-output":  # nothing on its screen to wait for
            time.sleep(5.0)
        elif not term.wait_for(port):
            raise SystemExit(f"{kind}: the capture did not start: {term.screen[-500:]!r}")
        if kind_as.startswith("attached"):  # a viewer without a UI: the frames as text, to /dev/null
            idle = ["chrt", "-i", "0"] if kind_as == "attached-idle" else []
            viewers = [subprocess.Popen([*idle, sys.executable, "-m", "sniffer", "attach", sock],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                       for _ in range(3 if kind_as == "attached3" else 1)]
        elif kind_as.startswith("burst"):  # no viewer: a plain process busy in bursts
            viewers = [subprocess.Popen([sys.executable, "-c", BURST, "plain" if kind_as == "burst" else "yield",
                                         str(seconds + 1.5), "0.0028" if kind_as == "burst28-yield" else "0.0013"])]
        time.sleep(1.0)
        feeder.stdin.write("go\n")
        feeder.stdin.flush()
        while True:
            term.read(0.2)
            line = feeder.stdout.readline() if _ready(feeder.stdout) else ""
            if line.startswith("done"):
                written_back = int(line.split()[1])
                break
        cpid = capture_pid(term.proc.pid, kind)
        capture_cpu = process_cpu_s(cpid) + sum(process_cpu_s(p) for p in reader_pids(cpid))
        if kind_as.startswith("tui"):
            term.type("q")
            term.wait_for("Stop the live capture", 10)
            term.type("y")
        else:
            os.kill(term.proc.pid, signal.SIGINT)
    finally:
        rc = term.finish()
        for v in viewers:
            v.wait(10)
        feeder.stdin.write("q\n")
        feeder.stdin.close()
        feeder.wait()
    cpu1 = os.times()
    return {"kind": label, "rc": rc, "written_back": written_back, "feeder": policy, "capture_cpu_s": capture_cpu,
            "children_cpu_s":
            (cpu1.children_user + cpu1.children_system) - (cpu0.children_user + cpu0.children_system),
            **figures(out, json.loads(times_path.read_text()))}


def capture_pid(pid: int, kind: str) -> int:
    """The capture process: the one started (headless), or the one the TUI started (its child running live)."""
    if not kind.startswith("tui"):
        return pid
    for child in children_with(pid, b"--publish"):
        return child
    raise SystemExit(f"{kind}: no capture process under {pid}")


def reader_pids(pid: int) -> list[int]:
    """The capture's port reader process (processes/reader.py), if it has one."""
    return children_with(pid, b"reader_process")


def children_with(pid: int, needle: bytes) -> list[int]:
    """The children of process `pid` whose command line holds `needle`."""
    return [int(child) for tid in os.listdir(f"/proc/{pid}/task")
            for child in Path(f"/proc/{pid}/task/{tid}/children").read_text().split()
            if needle in Path(f"/proc/{child}/cmdline").read_bytes()]


def process_cpu_s(pid: int) -> float:
    """CPU seconds (user + system) of process `pid` itself, its threads included, its children not."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _ready(f) -> bool:
    import select

    return bool(select.select([f], [], [], 0)[0])


def figures(mcap: Path, written: list[list[int]]) -> dict:
    """`written`: the feeder's (time before, time after) each frame's write.  A read holds a frame if it came
    after the write began; it is late by its time minus the write's end (0 at least: the feeder may take its
    time after the write later than the capture its read).  A response with no latency whose write ended
    less than LINE_GLUED_MS after its request's did not leave the feeder apart from it (the simulated line
    itself was late): counted apart, it says nothing about the capture."""
    recs = read_frames(str(mcap))
    by = {r["index"]: r for r in recs}
    rsp = [r for r in recs if r.get("role") == "response"]
    _, events = open_mcap(str(mcap))
    reads = sorted(ev.t_ns for ev in events if type(ev) is Chunk)
    late = sorted(max(0, reads[i] - end) / 1e6 for begin, end in written
                  if (i := bisect.bisect_left(reads, begin)) < len(reads))
    nolat = [r for r in rsp if r.get("latency_ms") is None]
    line_glued = 0
    if len(recs) == len(written):  # frame i of the capture is write i of the feeder
        line_glued = sum(1 for r in nolat if r.get("pair") in by
                         and (written[r["index"]][1] - written[r["pair"]][1]) / 1e6 < LINE_GLUED_MS)

    def q(p: float) -> float:
        return late[min(len(late) - 1, int(p * len(late)))] if late else float("nan")

    return {"frames": len(recs), "responses": len(rsp), "no_latency": len(nolat), "line_glued": line_glued,
            "before_request": sum(1 for r in rsp if r.get("pair") in by
                                  and r["t"] < by[r["pair"]].get("t_end", by[r["pair"]]["t"])),
            "late_p50": q(.5), "late_p90": q(.9), "late_p99": q(.99), "late_max": late[-1] if late else float("nan")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="stress")
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--kinds", default="headless,tui,tui-no-give-way")
    ap.add_argument("--keep", metavar="DIR", help="write the captures (KIND.mcap) here and keep them")
    ap.add_argument("--feeder", choices=("fifo", "normal"), default="fifo",
                    help="the feeder's scheduling: SCHED_FIFO (default, where permitted: the line is hardware, "
                    "this machine's load does not delay it) or normal (it competes with the sniffer)")
    ap.add_argument("--turnaround-ms", default="", metavar="LO,HI",
                    help="every unit answers LO to HI ms after its request (the stress line: 0.17-0.26 ms)")
    ap.add_argument("--peer", default="", metavar="DIR",
                    help="a kind ending in -peer runs the sniffer of the tree DIR (e.g. a git worktree of an "
                    "older commit, on PYTHONPATH): before and after a change, in the same rounds")
    a = ap.parse_args()
    if not a.peer and any(k.endswith("-peer") for k in a.kinds.split(",")):
        ap.error("a kind ending in -peer needs --peer DIR (the tree it runs)")
    print(f"{a.scenario}{', answers ' + a.turnaround_ms + ' ms after' if a.turnaround_ms else ''}, "
          f"{a.seconds:.0f} s per run, {os.cpu_count()} CPUs; load average at start "
          f"{os.getloadavg()[0]:.2f}")
    print(f"{'run':<16} {'responses':>9} {'no latency':>14} {'line':>5} {'capture':>14} {'before req':>10} "
          f"{'read late ms p50':>16} {'p90':>6} {'p99':>7} {'max':>7} {'load':>5} {'cap CPU s':>9}")
    if a.keep:
        Path(a.keep).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        d = a.keep or tmp
        for _ in range(a.repeat):
            for kind in a.kinds.split(","):
                r = run_one(kind, a.scenario, a.seconds, Path(d), a.feeder, a.turnaround_ms, a.peer)
                n, nolat, line = r["responses"], r["no_latency"], r["line_glued"]
                print(f"{kind:<16} {n:>9} {nolat:>6} ({100 * nolat / max(n, 1):4.1f} %) {line:>5} "
                      f"{nolat - line:>6} ({100 * (nolat - line) / max(n, 1):4.1f} %) "
                      f"{r['before_request']:>10} {r['late_p50']:>16.2f} {r['late_p90']:>6.2f} {r['late_p99']:>7.2f} "
                      f"{r['late_max']:>7.1f} {os.getloadavg()[0]:>5.2f} {r['capture_cpu_s']:>9.2f}"
                      + ("" if r["feeder"] == "SCHED_FIFO" else f"  (feeder {r['feeder']})")
                      + ("" if r["rc"] == 0 and r["written_back"] == 0 else
                         f"  (exit {r['rc']}, {r['written_back']} bytes written back!)"), flush=True)


if __name__ == "__main__":
    main()
