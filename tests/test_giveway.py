"""Issue 11: the viewer of a live capture hands its CPU back while frames come in (sniffer/processes/cpu_yield.py).

What the kernel does with the CPU given is measured by benchmarks/bench_capture_timing.py, not here: these
tests check when this process gives way (the interval timer as the kernel holds it, the handler installed),
never how fast anything happened.
"""

from __future__ import annotations

import asyncio
import ctypes
import signal
import subprocess
import sys
import threading
import time

import pytest

from tui_helpers import SIM

from decoders.registry import default_registry
from sniffer.processes.attach import Attachment, attach_feed
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.processes.publish_sink import PublishSink
from sniffer.formats.mcap.reader import read_frames
from sniffer.sources.files import open_replay
from sniffer.processes.cpu_yield import _LIBC, GIVE_WAY_S, GiveWay, _SigAction
from sniffer.tui.sink import TuiSink

HANG_S = 60.0  # a bound on waiting for something that should happen, never an assertion on speed


def _timer() -> float:
    """The process's interval timer as the kernel holds it: its period, 0 when it does not run."""
    return signal.getitimer(signal.ITIMER_REAL)[1]


def _alarm_handler() -> int | None:
    act = _SigAction()
    assert _LIBC.sigaction(signal.SIGALRM, None, ctypes.byref(act)) == 0
    return act.sa_handler


def _work(seconds: float, frames: list[int] | None = None) -> None:
    """This thread busy for `seconds` (frames coming in meanwhile if given)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if frames is not None:
            frames[0] += 1


def _until(cond, what: str, frames: list[int] | None = None) -> None:
    deadline = time.monotonic() + HANG_S
    while not cond():
        assert time.monotonic() < deadline, what
        _work(0.02, frames)


class Frames(threading.Thread):
    """Frames arriving every 10 ms from another thread, as the attachment's feed receives them."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.n = 0
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.wait(0.01):
            self.n += 1


def test_gives_way_only_while_frames_come_in_and_leaves_nothing_behind():
    before = _alarm_handler()
    frames = [0]
    with GiveWay(lambda: frames[0]) as gw:
        # SIGALRM is handled by sched_yield itself, in C (nothing of Python's runs per signal)
        assert _alarm_handler() == ctypes.cast(_LIBC.sched_yield, ctypes.c_void_p).value
        _work(0.3)
        assert _timer() == 0 and not gw.armed  # a quiet line: nothing
        _until(lambda: gw.armed, "frames came in, the timer never ran", frames)
        _work(0.3, frames)
        assert _timer() == pytest.approx(GIVE_WAY_S, abs=1e-5)  # every 0.2 ms while they come
        _until(lambda: not gw.armed, "the line went quiet, the timer still ran")  # after QUIET_S
        assert _timer() == 0
        _until(lambda: gw.armed, "frames came again, the timer did not run again", frames)
    assert _timer() == 0
    after = _alarm_handler()
    assert after == before or (before is None and after == 1)  # SIG_DFL became SIG_IGN: a late signal ends nothing


def test_a_viewer_process_lives_through_its_signals():
    """In a process of its own: busy under the timer, then a stray SIGALRM after the end; it exits 0."""
    code = (
        "import os, signal, time\n"
        "from sniffer.processes.cpu_yield import GiveWay\n"
        "n = [0]\n"
        "with GiveWay(lambda: n[0]) as gw:\n"
        "    end = time.monotonic() + 60\n"
        "    while not gw.armed and time.monotonic() < end:\n"
        "        n[0] += 1\n"
        "    t = time.monotonic()\n"
        "    while time.monotonic() - t < 0.5:\n"
        "        n[0] += 1\n"
        "    time.sleep(0.2)\n"  # a blocking call, interrupted and resumed
        "    assert gw.armed\n"
        "os.kill(os.getpid(), signal.SIGALRM)\n"
        "time.sleep(0.1)\n"
        "print('alive')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_S)
    assert r.returncode == 0 and r.stdout == "alive\n", r.stderr


def test_gives_way_while_the_apps_loop_works_not_while_it_waits():
    """Watched, the timer runs only while the loop runs callbacks: a waiting loop holds no CPU, and signals
    would only wake it."""
    feed = Frames()
    feed.start()
    got = {"waiting": set()}

    async def main():
        loop = asyncio.get_running_loop()
        inner = loop._selector.select
        waits = {"n": 0, "in": False}  # selector calls begun; this thread inside the selector's own select

        def select(timeout=None):  # under watch_loop's wrapper: its disarm comes before, its arm after
            waits["n"] += 1
            waits["in"] = True
            try:
                return inner(timeout)
            finally:
                waits["in"] = False

        loop._selector.select = select
        with GiveWay(lambda: feed.n) as gw:
            gw.watch_loop(loop)
            deadline = time.monotonic() + HANG_S
            while not gw.line_busy:
                assert time.monotonic() < deadline
                await asyncio.sleep(0.05)
            seen, stop = got["waiting"], threading.Event()

            def watch() -> None:  # the timer read only while the loop surely sat in its selector throughout
                while not stop.wait(0.01):
                    n, inside = waits["n"], waits["in"]
                    timer = _timer()
                    if inside and waits["in"] and waits["n"] == n:
                        seen.add(timer)

            watcher = threading.Thread(target=watch)
            watcher.start()
            while len(seen) < 1 or waits["n"] < 3:  # the loop waits in its selector most of the time
                assert time.monotonic() < deadline, "the loop never seen waiting"
                await asyncio.sleep(0.2)
            stop.set()
            watcher.join(HANG_S)
            _work(0.3)  # a callback that works (a redraw), right after the loop woke
            got["working"] = _timer()

    try:
        asyncio.run(main())
    finally:
        feed.stop.set()
    assert got["waiting"] == {0.0}, got  # never armed while the loop waited
    assert got["working"] == pytest.approx(GIVE_WAY_S, abs=1e-5), got


def test_the_attached_feed_gives_way_between_two_records(tmp_path):
    """The feed thread cannot take the timer's signal (Python runs handlers in the main thread): it calls
    pause() itself, once per line the capture sent."""
    sock = str(tmp_path / "feed.sock")
    name = "errors.mcap"
    info, events = open_replay(str(SIM / name))
    pub = PublishSink(sock, label=name)
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1),
                 default_registry(info.devices), [pub], protocol=info.protocol)
    att = Attachment(sock)
    pauses = [0]

    def pause() -> None:
        pauses[0] += 1

    sink, stop = TuiSink(), threading.Event()
    done = threading.Event()
    viewer = threading.Thread(target=lambda: (attach_feed(att, pause=pause)(sink, stop), done.set()), daemon=True)
    viewer.start()
    for ev in events:
        p.feed(ev)
    p.finish()
    assert done.wait(HANG_S), "the feed never saw the capture end"
    n = len(read_frames(str(SIM / name)))
    assert sink.frames_in == n > 50
    assert pauses[0] >= n  # every frame record, and the control lines (status, reads, end) besides
