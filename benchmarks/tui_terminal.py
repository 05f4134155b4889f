"""The TUI as a user feels it: key-to-screen latency and CPU of the real command on a terminal (a pty).

    .venv/bin/python benchmarks/tui_terminal.py [--keys 80] [--seconds 60] [--replay-frames 200000] [--repeat 1]

(bench_tui.py runs the same as its headline section.)  The command runs on a pty of its own
(tests/terminal.py) and pyte keeps the screen it draws.  A key is written to the pty, and the time
until the screen shows its effect is the latency: Home moves the highlighted row (the frame list's
cursor, framelist.S_CURSOR's background) to the list's first row, End back to its last row (where
it sits while following the tail).  The keys alternate Home / End, 0.15-0.35 s apart after each
effect (a person's pace), so every key has an effect to wait for.

Scenarios:
* live stress   `sniffer demo --scenario stress --duration S --no-out`: the capture in its own child
                process, the TUI (the command's process) attached to it.  The CPU (utime + stime from
                /proc/PID/stat, % of one core) of the TUI and of the capture child is measured over a
                window where nobody types (the view follows the tail, as a user watching does); the
                keys come after it.
* headless      `sniffer demo --scenario stress --headless --quiet --no-out`: the capture's CPU with no
                viewer, over the same window (the peer: a viewer must not change the capture's CPU).
* loading       `sniffer replay BIG.mcap --tui` of a simulated stress capture (about 200k frames,
                made once and kept in the temp dir): keys pressed while it still loads (before the
                status bar says [ended]); replays are restarted until enough keys are in.
* idle replay   the same replay once loaded: the same keys on an idle TUI (the peer for the others).

Figures are printed, nothing is asserted.  The bench's own pyte parsing takes CPU on the same machine
(its share is printed): on a 2-CPU machine shared with other work every figure is noisy, so the load
average is printed beside them.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import os
import random
import select
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import pyte
from terminal import Terminal, children

from sniffer.tui.framelist import S_CURSOR

SNIFFER = [sys.executable, "-m", "sniffer"]
COLS, ROWS = 120, 40
HOME, END = "\x1b[H", "\x1b[F"  # xterm's Home / End
CURSOR_BG = S_CURSOR.bgcolor.get_truecolor().hex.lstrip("#")  # as pyte names a 256-colour background
EFFECT_TIMEOUT_S = 10.0
TICK = os.sysconf("SC_CLK_TCK")


# ------------------------------------------------------------------ a terminal that keeps its screen
_running: set[Terminal] = set()  # killed if the bench is (a TUI left behind would load the machine for hours)


@atexit.register
def _kill_running() -> None:
    for term in list(_running):
        if term.proc.poll() is None:
            with contextlib.suppress(OSError):
                os.killpg(term.proc.pid, signal.SIGKILL)  # its session: the TUI and a capture child
            term.proc.wait()
        _running.discard(term)


class Screen:
    """A command on a pty (tests/terminal.Terminal) with pyte keeping what it draws."""

    def __init__(self, argv: list[str], cols: int = COLS, rows: int = ROWS, cwd: str | None = None) -> None:
        self.term = Terminal(argv, cols, rows, cwd)
        _running.add(self.term)
        self.screen = pyte.Screen(cols, rows)
        self.stream = pyte.ByteStream(self.screen)
        self.pid = self.term.proc.pid

    def pump(self, seconds: float = 0.0, until=None) -> float | None:
        """Read and draw what the command writes for `seconds`, or until `until(self)` holds: then the time
        (perf_counter) of the read that made it hold; None if it never did (or the command ended)."""
        fd = self.term.master
        deadline = time.perf_counter() + seconds
        while True:
            left = deadline - time.perf_counter()
            if left <= 0:
                return None
            if not select.select([fd], [], [], min(left, 0.05))[0]:
                if self.term.proc.poll() is not None:
                    return None
                continue
            try:
                data = os.read(fd, 1 << 16)
            except OSError:  # EIO: the command closed the terminal
                return None
            t = time.perf_counter()
            if not data:
                return None
            self.stream.feed(data)
            if until is not None and until(self):
                return t

    def text(self, y: int) -> str:
        return self.screen.display[y]

    def find(self, text: str) -> int | None:
        return next((y for y, line in enumerate(self.screen.display) if text in line), None)

    def cursor_row(self) -> int | None:
        """The screen row with the frame list's cursor (its background, looked at in the time column)."""
        buf = self.screen.buffer
        for y in range(self.screen.lines):
            if buf[y][6].bg == CURSOR_BG and buf[y][12].bg == CURSOR_BG:
                return y
        return None

    def type(self, keys: str) -> float:
        t = time.perf_counter()
        self.term.type(keys)
        return t

    def quit(self, confirm: bool = False) -> int:
        self.type("q")
        if confirm:
            self.pump(1.0)
            try:
                self.type("y")
            except OSError:  # it had ended already: q closed it
                pass
        rc = self.term.finish(30)
        _running.discard(self.term)
        return rc


# ------------------------------------------------------------------ CPU from /proc
def cpu_s(pid: int) -> float:
    """utime + stime of a process, seconds (every thread)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


class CpuWindow:
    """CPU of some processes (and of this one) between start() and stop(), as % of one core."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.pct: dict[str, float] = {}

    def start(self) -> None:
        self.t0 = time.perf_counter()
        self.c0 = {k: cpu_s(p) for k, p in self.pids.items()}
        self.self0 = sum(os.times()[:2])

    def stop(self) -> dict[str, float]:
        dt = time.perf_counter() - self.t0
        self.pct = {k: 100 * (cpu_s(p) - self.c0[k]) / dt for k, p in self.pids.items()}
        self.pct["bench (pyte)"] = 100 * (sum(os.times()[:2]) - self.self0) / dt
        return self.pct


# ------------------------------------------------------------------ keys
@dataclass
class Keys:
    label: str
    latencies: list[float] = field(default_factory=list)  # seconds
    lost: int = 0  # keys whose effect never showed within EFFECT_TIMEOUT_S
    load: list[float] = field(default_factory=list)  # 1-minute load average when the keys were pressed

    def stats(self) -> dict:
        lat = sorted(self.latencies)
        if not lat:
            return {"n": 0}
        q = statistics.quantiles(lat, n=100, method="inclusive") if len(lat) > 1 else [lat[0]] * 99
        return {"n": len(lat), "median": statistics.median(lat) * 1e3, "p90": q[89] * 1e3, "p99": q[98] * 1e3,
                "max": lat[-1] * 1e3, "lost": self.lost, "load": statistics.mean(self.load) if self.load else 0}


def press(scr: Screen, keys: Keys, n: int, rows: tuple[int, int], *, still=lambda s: True,
          pace: tuple[float, float] = (0.15, 0.35), rng: random.Random | None = None) -> None:
    """Alternate Home / End `n` times (while `still(scr)`), timing each to its effect on the cursor row."""
    top, bottom = rows
    rng = rng or random.Random(1)
    done = len(keys.latencies) + keys.lost + n
    for _ in range(n):
        for key, want in ((HOME, top), (END, bottom)):
            scr.pump(rng.uniform(*pace))
            if not still(scr):
                return
            keys.load.append(os.getloadavg()[0])
            t = scr.type(key)
            shown = scr.pump(EFFECT_TIMEOUT_S, until=lambda s, y=want: s.cursor_row() == y)
            if shown is None:
                keys.lost += 1
                if scr.term.proc.poll() is not None:
                    return
            else:
                keys.latencies.append(shown - t)
            if len(keys.latencies) + keys.lost >= done:
                return


def list_rows(scr: Screen, timeout_s: float = 30.0) -> tuple[int, int] | None:
    """(first, last) screen rows of the frame list once it follows a full screen of frames: the row under the
    header, and the cursor's row (the last one while following)."""
    head = None

    def ready(s: Screen) -> bool:
        nonlocal head
        head = s.find("frame→pair")
        y = s.cursor_row()
        return head is not None and y is not None and y > head + 5

    if not ready(scr) and scr.pump(timeout_s, until=ready) is None:
        return None
    return head + 1, scr.cursor_row()


# ------------------------------------------------------------------ scenarios
def live_stress(seconds: float, n_keys: int, cpu_window_s: float) -> tuple[Keys, dict]:
    scr = Screen([*SNIFFER, "demo", "--scenario", "stress", "--duration", str(seconds), "--no-out"])
    keys = Keys("live stress")
    cpu: dict = {}
    try:
        rows = list_rows(scr)
        if rows is None:
            raise RuntimeError("live stress: the TUI never showed a list: " + "\n".join(scr.screen.display))
        kids = children(scr.pid)
        pids = {"tui": scr.pid, **({"capture child": kids[0]} if kids else {})}
        grandkids = children(kids[0]) if kids else []
        if grandkids:  # the capture's publisher process, which serves the TUI (sniffer/processes/publisher.py)
            pids["its publisher"] = grandkids[0]
        scr.pump(2.0)  # settled
        win = CpuWindow(pids)
        win.start()
        scr.pump(cpu_window_s)
        cpu = win.stop()
        cpu["load"] = os.getloadavg()[0]
        press(scr, keys, n_keys, rows, still=lambda s: s.term.proc.poll() is None)
    finally:
        scr.quit(confirm=True)
    return keys, cpu


def headless_cpu(cpu_window_s: float) -> dict:
    """The capture with no viewer: its CPU over a window like the live one's (after the same settling)."""
    argv = [*SNIFFER, "demo", "--scenario", "stress", "--duration", str(cpu_window_s + 10), "--no-out",
            "--headless", "--quiet"]
    p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(4.0)
        win = CpuWindow({"capture (headless)": p.pid})
        win.start()
        time.sleep(cpu_window_s)
        out = win.stop()
        out["load"] = os.getloadavg()[0]
        out.pop("bench (pyte)")
        return out
    finally:
        p.terminate()
        p.wait()


def big_capture(frames: int) -> Path:
    """A simulated stress capture of about `frames` frames, made once and kept in the temp dir."""
    per_s = 372  # the stress scenario's frames per bus second
    duration = frames // per_s + 1
    path = Path(tempfile.gettempdir()) / "sniffer-bench-tui" / f"stress{duration}s.mcap"
    path.parent.mkdir(exist_ok=True)
    if not path.exists():
        print(f"(making {path}: sniffer simulate --scenario stress --duration {duration})", flush=True)
        subprocess.run([*SNIFFER, "simulate", "--scenario", "stress", "--duration", str(duration), "--seed", "7",
                        "--out", str(path)], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return path


def _loading(s: Screen) -> bool:
    return "[ended]" not in s.text(ROWS - 2)


def replay(path: Path, n_keys: int, max_runs: int = 8) -> tuple[Keys, Keys, list[float]]:
    """Keys while a big replay loads (restarted until n_keys are in), and the same keys once it has loaded.
    Also the seconds each load took (start to [ended])."""
    loading, idle, load_s = Keys("replay loading"), Keys("replay idle"), []
    rng = random.Random(2)
    for _ in range(max_runs):
        t0 = time.perf_counter()
        # run where the file is: a short name keeps the status bar's [ended] on a 120-column screen
        scr = Screen([*SNIFFER, "replay", path.name, "--tui"], cwd=str(path.parent))
        try:
            rows = list_rows(scr)
            if rows is None:
                raise RuntimeError("replay: the TUI never showed a list:\n" + "\n".join(scr.screen.display))
            press(scr, loading, n_keys - len(loading.latencies), rows, still=_loading, rng=rng)
            ended = scr.pump(600, until=lambda s: not _loading(s)) if _loading(scr) else time.perf_counter()
            if ended is not None:
                load_s.append(ended - t0)
            if len(idle.latencies) < n_keys:
                scr.pump(1.0)
                press(scr, idle, n_keys, rows, rng=rng)
        finally:
            scr.quit()
        if len(loading.latencies) >= n_keys:
            break
    return loading, idle, load_s


# ------------------------------------------------------------------ report
def _row(keys: Keys, width: int) -> str:
    s = keys.stats()
    if not s["n"]:
        return f"  {keys.label:{width}s} no keys"
    return (f"  {keys.label:{width}s} {s['n']:4d} {s['median']:8.0f} {s['p90']:8.0f} {s['p99']:8.0f} {s['max']:8.0f} "
            f"{s['lost']:5d}   {s['load']:4.1f}")


def _merge(label: str, parts: list[Keys]) -> Keys:
    out = Keys(label)
    for k in parts:
        out.latencies += k.latencies
        out.lost += k.lost
        out.load += k.load
    return out


def _print_keys(rows: list[Keys], peer: Keys | None) -> None:
    width = max(len(k.label) for k in rows)
    print(f"  {'scenario':{width}s} {'keys':>4} {'median':>8} {'p90':>8} {'p99':>8} {'max':>8} {'lost':>5}   load")
    for k in rows:
        print(_row(k, width))
    peer_med = peer.stats().get("median") if peer is not None else None
    for k in rows:
        med = k.stats().get("median")
        if k is not peer and med and peer_med:
            print(f"  {k.label}: median {med / peer_med:.1f}x the idle replay's (the peer: the same keys, "
                  f"nothing loading)")


def _print_cpu(cpu: dict, headless: dict, window_s: float) -> None:
    print(f"  CPU over {window_s:.0f} s of live stress, nobody typing, % of one core (load {cpu['load']:.1f}): "
          + ", ".join(f"{k} {v:.0f} %" for k, v in cpu.items() if k != "load"))
    print(f"  the capture headless (the peer), the same window (load {headless['load']:.1f}): "
          f"{headless['capture (headless)']:.0f} %", flush=True)


@contextlib.contextmanager
def tree(path: str | None):
    """The commands run the sniffer of checkout `path` (None: this one) while inside."""
    old = os.environ.get("PYTHONPATH")
    if path is not None:
        os.environ["PYTHONPATH"] = str(Path(path).resolve())
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH", None)
        else:
            os.environ["PYTHONPATH"] = old


def run(n_keys: int = 80, seconds: float = 60.0, replay_frames: int = 200_000, repeat: int = 1,
        cpu_window_s: float = 15.0, scenarios: tuple[str, ...] = ("live", "replay"),
        trees: dict[str, str | None] | None = None) -> dict:
    """The scenarios, `repeat` times, for each checkout in `trees` (label -> path, None: this one), one after
    the other within a run; prints each run's tables and, after several, the keys of all runs."""
    trees = trees or {"": None}
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a bench stopped with kill still stops its TUIs
    print(f"terminal {COLS}x{ROWS} (pty + pyte), keys Home / End alternating, {n_keys} a scenario; "
          f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}", flush=True)
    path = big_capture(replay_frames) if "replay" in scenarios else None
    res: dict[str, dict[str, list]] = {}
    for i in range(repeat):
        for label, where in trees.items():
            r = res.setdefault(label, {"live": [], "cpu": [], "headless": [], "loading": [], "idle": [],
                                       "load_s": []})
            tag = f" ({label})" if label else ""
            rows: list[Keys] = []
            idle = None
            with tree(where):
                if "live" in scenarios:
                    keys, cpu = live_stress(seconds, n_keys, cpu_window_s)
                    keys.label += tag
                    r["live"].append(keys)
                    r["cpu"].append(cpu)
                    r["headless"].append(headless_cpu(cpu_window_s))
                    rows.append(keys)
                if path is not None:
                    loading, idle, load_s = replay(path, n_keys)
                    loading.label += tag
                    idle.label += tag
                    r["loading"].append(loading)
                    r["idle"].append(idle)
                    r["load_s"] += load_s
                    rows += [loading, idle]
            print(f"\nrun {i + 1}/{repeat}{tag}: key-to-screen latency, ms")
            _print_keys(rows, idle)
            if path is not None:
                print(f"  {path.name} loaded in " + ", ".join(f"{s:.0f} s" for s in load_s) + " (to [ended])")
            if "live" in scenarios:
                _print_cpu(r["cpu"][-1], r["headless"][-1], cpu_window_s)
    if repeat > 1 or len(trees) > 1:
        print(f"\nall {repeat} runs: key-to-screen latency, ms")
        rows = []
        for label, r in res.items():
            tag = f" ({label})" if label else ""
            rows += [_merge(name + tag, r[key]) for key, name in (("live", "live stress"),
                                                                  ("loading", "replay loading"),
                                                                  ("idle", "replay idle")) if r[key]]
        _print_keys(rows, None)
        for label, r in res.items():
            tag = f" ({label})" if label else ""
            for key in ("cpu", "headless"):
                for name in sorted({k for c in r[key] for k in c if k != "load"}):
                    print(f"  CPU {name}{tag}: " + ", ".join(f"{c[name]:.0f} %" for c in r[key]) + " (load "
                          + ", ".join(f"{c['load']:.1f}" for c in r[key]) + ")")
            if r["load_s"]:
                print(f"  replay loaded{tag} in " + ", ".join(f"{s:.0f} s" for s in r["load_s"]))
    return res


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--keys", type=int, default=80, help="keys per scenario")
    ap.add_argument("--seconds", type=float, default=60.0, help="the live stress demo's --duration")
    ap.add_argument("--replay-frames", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--scenarios", default="live,replay", help="live (with the headless peer), replay")
    ap.add_argument("--before", metavar="DIR", help="also run the sniffer of checkout DIR (e.g. a worktree of "
                    "the commit before a change), after this one's in every run: before / after on one machine load")
    a = ap.parse_args(argv)
    trees = {"": None} if a.before is None else {"this tree": None, f"before: {Path(a.before).name}": a.before}
    run(a.keys, a.seconds, a.replay_frames, a.repeat, scenarios=tuple(a.scenarios.split(",")), trees=trees)


if __name__ == "__main__":
    main()
