"""The TUI says when most frames are bad (a notification and a mark in the status bar), and Ctrl-C in the TUI
of a live capture asks before it stops it, as `q` does (not Textual's "press ctrl+q" notice)."""

from __future__ import annotations

import asyncio
import itertools
import sys

from helpers import simulated
from terminal import Terminal
from tui_helpers import demo_viewer, replay_frames

from sniffer.analysis.linehealth import is_line_warning
from sniffer.capture.session import CaptureSpec, Session
from sniffer.formats.mcap.reader import read_frames
from sniffer.sources.segset import capture_source
from sniffer.tui.app import SnifferApp
from sniffer.tui.linenotice import LineNotice
from sniffer.tui.run import session_app
from sniffer.tui.sink import TuiSink
from sniffer.tui.status import status_text

SIZE = (140, 45)
MARK = "most frames bad: line settings?"


def run(coro):
    return asyncio.run(coro)


async def until(pilot, cond, tries: int = 400, step_s: float = 0.05) -> bool:
    for _ in range(tries):
        if cond():
            return True
        await pilot.pause(step_s)
    return cond()


def warnings_shown(app) -> list[str]:
    return [str(n.message) for n in app._notifications if "probably wrong" in str(n.message)]


def replay_app(path: str):
    sink = TuiSink()
    session = Session(CaptureSpec(input=path), capture_source(path), [sink])
    session.open()
    return session_app(session, sink, source_label=path, source_path=path)


def test_a_replay_at_the_wrong_baud_is_said_and_marked(tmp_path_factory):
    wrong = str(simulated(tmp_path_factory, "wrong.mcap", "--scenario", "default", "--receiver-baud", "9600",
                          "--duration", "10"))

    async def go():
        app = replay_app(wrong)
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: warnings_shown(app))
            assert await until(pilot, lambda: app.caught_up)
            await pilot.pause(0.1)
            said = warnings_shown(app)
            assert len(said) == 1 and "(9600 8E1)" in said[0] and "sniffer detect" in said[0], said
            assert MARK in status_text(app, 200).plain  # the mark stays while the line is bad
            await pilot.press("q")  # a replay: no question
    run(go())


def test_a_live_capture_at_the_wrong_baud_is_said_once_and_marked(tmp_path, capsys):
    """The real path: a pty line at 19200 8E1 captured at 9600 by its own process, the App attached to it.  The
    capture says the warning on its stderr (held for the App, printed when it closes); the App says it once."""
    from helpers import SimulatedLine

    from sniffer.capture.settings import LineChoice
    from sniffer.tui.run import CaptureViewer

    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: warnings_shown(app), 600)
            await pilot.pause(0.5)
            said = warnings_shown(app)
            assert len(said) == 1 and f"run sniffer detect {line.path} " in said[0] and "(9600 8N1)" in said[0]
            assert MARK in status_text(app, 200).plain
            await pilot.press("q", "y")

    with SimulatedLine(tmp_path, "default") as line:
        spec = CaptureSpec(flags=LineChoice(baud=9600), port=line.path, out=str(tmp_path / "w.mcap"))
        with CaptureViewer(spec, "live", line.path) as viewer:
            assert viewer.start()
            run(go(viewer.app))
    assert viewer.rc() == 0
    err = capsys.readouterr().err  # what the capture said, held while the App ran, printed once it closed
    assert sum(is_line_warning(x) for x in err.splitlines()) == 1


def test_a_healthy_capture_with_errors_is_neither_said_nor_marked():
    info, frames, registry = replay_frames("errors.mcap")

    async def go():
        sink = TuiSink()
        sink.start(info)
        sink.frames(frames)
        sink.close()
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: app.caught_up)
            assert len(app.store) > 100 and warnings_shown(app) == [] and MARK not in status_text(app, 200).plain
    run(go())


def test_the_capture_process_warning_is_not_shown_twice():
    """A capture on this machine says the warning on its stderr (a notice to its viewer): the App says its own."""
    info, frames, registry = replay_frames("errors.mcap")

    async def go():
        sink = TuiSink()
        sink.start(info)
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0, poll_hz=0.001)
        async with app.run_test(size=SIZE) as pilot:
            line = ("sniffer: warning: 40 of 40 frames (100% of the bytes) in 1.0 s are CRC errors, UART errors or "
                    "noise (noise 40): the line settings (9600 8E1) are probably wrong; run sniffer detect /dev/x")
            assert is_line_warning(line)
            app.notices.extend([line, "sniffer: port lost (unplugged?)"])
            app.poll()
            await pilot.pause()
            shown = [str(n.message) for n in app._notifications]
            assert shown == ["port lost (unplugged?)"]
    run(go())


def test_recovery_and_a_new_break_notify_again_once(tmp_path_factory):
    """Bad frames, good ones, bad again: two warnings; the mark comes, goes and comes back."""
    from sniffer.frame import Frame

    wrong = str(simulated(tmp_path_factory, "wrong.mcap", "--scenario", "default", "--receiver-baud", "9600",
                          "--duration", "10"))
    info, _, _ = replay_frames("default.mcap")
    s = 1_000_000_000

    def moved(path, t0_ns):  # the capture's frames, from its records, starting at t0_ns
        return [Frame(0, t0_ns + int(r["t"] * s), t0_ns + int(r["t"] * s) + 1, bytes.fromhex(r["raw"]), r["protocol"],
                      crc_ok=r.get("crc_ok")) for r in read_frames(path)]

    default = str(tmp_path_factory.getbasetemp() / "default.mcap")
    seq = moved(wrong, 0) + moved(_sim_default(default), 20 * s) + moved(wrong, 60 * s)
    notice = LineNotice("x.mcap")
    said, marks = [], []
    for i in range(0, len(seq), 50):
        said += notice.take(seq[i:i + 50], info)
        marks.append(bool(notice.mark()))
    assert len(said) == 2 and all("probably wrong" in x for x in said)
    runs = [k for k, _ in itertools.groupby(marks)]
    assert runs == [False, True, False, True]  # judged once there is enough, marked, recovered, marked again


def _sim_default(path: str) -> str:
    from sniffer.cli import main

    assert main(["simulate", "--scenario", "default", "--duration", "30", "--out", path]) == 0
    return path


# ---------------------------------------------------------------- Ctrl-C


def test_ctrl_c_in_a_live_capture_asks_and_y_stops_it(tmp_path):
    async def go(app, capture):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: len(app.store) > 10)
            await pilot.press("ctrl+c")
            await pilot.pause(0.05)
            assert type(app.screen).__name__ == "ConfirmQuit"  # not Textual's "press ctrl+q" notice
            assert not any("ctrl+q" in str(n.message) for n in app._notifications)
            await pilot.press("n")
            await pilot.pause(0.05)
            assert type(app.screen).__name__ != "ConfirmQuit" and app._thread.is_alive()
            n = len(app.store)
            assert await until(pilot, lambda: len(app.store) > n)  # still capturing
            assert capture.returncode is None
            await pilot.press("ctrl+c", "y")

    with demo_viewer(tmp_path, "default", 60) as viewer:
        run(go(viewer.app, viewer.capture))
    assert viewer.rc() == 0 and not (tmp_path / "d.mcap.part").exists()
    assert len(read_frames(str(tmp_path / "d.mcap"))) >= len(viewer.app.store.frames) > 10


def test_ctrl_c_twice_stops_a_live_capture(tmp_path):
    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: len(app.store) > 10)
            await pilot.press("ctrl+c", "ctrl+c")
            await pilot.pause(0.1)
            assert app._exit  # the App quits on its own (not when the test leaves it)

    with demo_viewer(tmp_path, "default", 60) as viewer:
        run(go(viewer.app))
    assert viewer.rc() == 0 and (tmp_path / "d.mcap").exists() and not (tmp_path / "d.mcap.part").exists()


def test_ctrl_c_in_a_replay_just_closes():
    info, frames, registry = replay_frames("errors.mcap")

    async def go():
        sink = TuiSink()
        sink.start(info)
        sink.frames(frames[:50])
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("ctrl+c")
            await pilot.pause(0.1)
            assert app._exit
    run(go())


def test_ctrl_c_on_a_real_terminal_asks_then_stops_and_closes_the_file(tmp_path):
    out = tmp_path / "d.mcap"
    term = Terminal([sys.executable, "-m", "sniffer", "demo", "--scenario", "default", "--duration", "120",
                     "--out", str(out)])
    try:
        assert term.wait_for("Transactions"), term.screen[-2000:]  # a tab's label: the App runs
        term.type("\x03")  # Ctrl-C, as the terminal sends it
        assert term.wait_for("Stop the live capture"), term.screen[-2000:]
        term.type("y")
    finally:
        rc = term.finish()
    assert rc == 0, term.screen[-3000:]
    assert out.exists() and not (tmp_path / "d.mcap.part").exists() and len(read_frames(str(out))) > 5
