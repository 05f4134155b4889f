"""The TUI under Textual's Pilot, at a fixed size, over a deterministic replay."""

import asyncio

import pytest
from tui_helpers import demo_viewer, filled_sink, registry_shadow, replay_frames, touches

from sniffer.formats.mcap.reader import read_frames
from sniffer.tui.app import SnifferApp
from sniffer.tui.store import F_PROBLEM
from sniffer.tui.sink import INTAKE_CHUNK, TuiSink

SIZE = (140, 45)


def make_app(name="errors.mcap") -> SnifferApp:
    _, _, registry = replay_frames(name)
    return SnifferApp(filled_sink(name), None, source_label=name, registry=registry, clock=lambda: 0.0)


def growing_app(n: int):
    """(app, sink, frames): an App over a sink holding errors.mcap's first n frames (the test adds more and
    polls itself: the poll timer is off)."""
    info, frames, registry = replay_frames()
    sink = TuiSink()
    sink.start(info)
    sink.frames(frames[:n])
    return SnifferApp(sink, None, registry=registry, clock=lambda: 0.0, poll_hz=0.001), sink, frames


async def loaded(app, pilot):
    app.poll()  # the timer would do the same within 1/15 s
    await pilot.pause()
    assert app.caught_up
    return app


def run(coro):
    return asyncio.run(coro)


async def until(pilot, cond, tries: int = 200, step_s: float = 0.05) -> bool:
    """Let the app run until `cond()` holds (True) or `tries` pauses have passed (False)."""
    for _ in range(tries):
        if cond():
            return True
        await pilot.pause(step_s)
    return cond()


def test_loads_and_follows_tail():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            n = len(app.store)
            assert n == len(replay_frames()[1])
            assert app.frame_list.cursor == n - 1 and app.frame_list.follow
            # the tail's newest frame, at once or (the timer took frames in first) within FOLLOW_EVERY_S
            assert await until(pilot, lambda: app.detail.frame is app.store.frames[-1])
    run(go())


def test_select_frame_and_detail_and_pair_jump():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down")
            f = app.selected_frame
            assert f is app.store.frames[2] and not app.frame_list.follow
            assert app.detail.frame is f
            assert f.role == "request" and f.pair is not None
            await pilot.press("p")
            g = app.selected_frame
            assert g.index == f.pair and g.pair == f.index and g.role == "response"
            assert app.detail.frame is g
            await pilot.press("p")
            assert app.selected_frame is f
            await pilot.press("enter")  # into the detail tree; its nodes light bytes up
            tree = app.detail.query_one("Tree")
            assert app.focused is tree
            spans = [app.detail.span]  # entering the tree selects the first point
            for _ in range(12):
                await pilot.press("down")
                spans.append(app.detail.span)
            # fc16 request: the written registers' bytes (after unit, fc, addr, count, byte count)
            assert (7, 9) in spans and (9, 11) in spans
            await pilot.press("escape")  # issue 11: Esc leaves the detail tree
            assert app.focused is app.frame_list
            await pilot.press("3")  # the Registers tab takes the keys when opened
            assert app.focused is app.query_one("#regwatch").query_one("DataTable")
            await pilot.press("2")
            assert app.focused is app.query_one("#unitstable")
    run(go())


def test_filter_by_unit_and_clear():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down")  # unit 2
            await pilot.press("u")
            assert app.store.filter.units == {2}
            view = app.store.view
            assert 0 < len(view) < len(app.store)
            assert all(app.store.frames[r].unit == 2 for r in view)
            assert app.selected_frame.index == 2  # the selection survives the filter
            await pilot.press("u")
            assert app.store.filter.units is None and len(app.store.view) == len(app.store)
    run(go())


def test_filter_bar():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("slash")
            await pilot.press(*"u:1 fc:3 role:rsp")
            await pilot.press("enter")
            f = app.store.filter
            assert f.units == {1} and f.functions == {3} and f.roles == {"response"}
            assert app.store.view and all(app.store.frames[r].unit == 1 for r in app.store.view)
            await pilot.press("c")
            assert not app.store.filter.active
    run(go())


async def type_filter(pilot, text: str) -> None:
    """'/' then the text, key by key as a user types it, then Enter."""
    await pilot.press("slash")
    await pilot.press(*text)
    await pilot.press("enter")


def test_filter_bar_finds_the_frames_touching_a_register():
    async def go():
        app = make_app("a510.mcap")
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await type_filter(pilot, "reg:2520H")
            frames = replay_frames("a510.mcap")[1]
            want = [r for r, f in enumerate(frames) if touches(f, 0x2520)]
            assert list(app.store.view) == want and len(want) > 20
            assert {app.store.frames[r].role for r in want} == {"request", "response"}
            assert app.focused is app.frame_list and "reg:2520H" in str(app.status.render())
            await pilot.press("u")  # the unit key narrows it further, beside the bar's filter
            unit = app.selected_frame.unit
            assert list(app.store.view) == [r for r in want if frames[r].unit == unit]
    run(go())


def test_filter_bar_value_filter_and_the_bar_reopens_on_it():
    async def go():
        app = make_app("a510.mcap")
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await type_filter(pilot, '"Output frequency" > 30 u:1')
            frames = replay_frames("a510.mcap")[1]
            want = [r for r, f in enumerate(frames) if f.unit == 1 and any(
                p["name"] == "Output frequency" and p["value"] > 30 for p in f.points)]
            assert list(app.store.view) == want and want
            assert app.store.filter.units == {1}  # the plain u: is the field the u key toggles
            await pilot.press("slash")
            assert app.filter_bar.value == 'u:1 "Output frequency" > 30'  # the filter in force, canonical
            await pilot.press("enter")
            assert list(app.store.view) == want
    run(go())


def test_free_text_finds_a_register_the_summary_does_not_name(stress_mcap):
    """Issue 11: `holding[300]` found 0 frames of the stress scenario though register 300 is read every
    cycle (a summary names 6 of the 125 registers)."""
    async def go():
        app = SnifferApp(filled_sink(stress_mcap), None, source_label="stress", clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await type_filter(pilot, "holding[300]")
            frames = replay_frames(stress_mcap)[1]
            want = [r for r, f in enumerate(frames) if touches(f, 300)]
            assert len(want) > 20 and list(app.store.view) == want
            assert not any("holding[300]" in frames[r].summary for r in want)
    run(go())


def test_a_bad_filter_says_where_and_the_old_one_stays():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE, notifications=True) as pilot:
            await loaded(app, pilot)
            await type_filter(pilot, "u:2 fc:3")
            view = list(app.store.view)
            assert view and app.store.filter.units == {2}
            await pilot.press("slash", "end", *" (lat>", "enter")
            errors = [n.message for n in app._notifications if n.severity == "error"]
            assert errors == ["filter error at column 15: '>' needs a value after it"]
            assert app.filter_bar.has_class("shown") and app.focused is app.filter_bar  # fix it in place
            assert app.filter_bar.value == "u:2 fc:3 (lat>"
            assert list(app.store.view) == view and app.store.filter.units == {2}  # the old filter stays
            await pilot.press("backspace", *"20ms)", "enter")
            assert app.focused is app.frame_list
            assert all(app.store.frames[r].latency_ms > 20 for r in app.store.view)
            assert set(app.store.view) < set(view)
    run(go())


def test_errors_only_and_jump_to_next_error():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home")
            start = app.frame_list.selected_row
            await pilot.press("n")
            r1 = app.frame_list.selected_row
            assert r1 > start and app.store.flags[r1] & F_PROBLEM
            assert all(not app.store.flags[r] & F_PROBLEM for r in range(start + 1, r1))
            await pilot.press("n")
            r2 = app.frame_list.selected_row
            assert r2 > r1 and app.store.flags[r2] & F_PROBLEM
            await pilot.press("N")
            assert app.frame_list.selected_row == r1
            await pilot.press("e")
            assert app.store.filter.errors_only
            assert all(app.store.flags[r] & F_PROBLEM for r in app.store.view)
            assert app.frame_list.selected_row == r1
    run(go())


def test_pause_keeps_view_while_frames_arrive():
    async def go():
        _, frames, registry = replay_frames()
        from sniffer.tui.sink import TuiSink

        sink = TuiSink()
        sink.start(replay_frames()[0])
        sink.frames(frames[:50])
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            await pilot.press("space")
            assert app.store.paused
            sink.frames(frames[50:])
            app.poll()
            await pilot.pause()
            assert len(app.store) == len(frames) and len(app.store.view) == 50
            assert app.frame_list.cursor == 49
            await pilot.press("space")
            assert not app.store.paused and len(app.store.view) == len(frames)
            assert app.frame_list.cursor == len(frames) - 1  # back to following the tail
    run(go())


def test_the_timer_takes_a_backlog_in_by_turns_every_frame_in_order(monkeypatch):
    """Issue 11: a poll took 5,000 frames in at once (half a second while a replay loaded, keys waiting).
    The timer takes frames in by turns of a time budget, and between polls while frames wait; with a
    budget of 0 every turn takes one frame, and still every frame arrives, in order, and is shown."""
    import sniffer.tui.app as app_module

    monkeypatch.setattr(app_module, "INTAKE_BUDGET_S", 0.0)
    monkeypatch.setattr(app_module, "INTAKE_TURN_S", 0.0)

    async def go():
        info, frames, registry = replay_frames()
        frames = frames[:40]
        sink = TuiSink()
        sink.start(info)
        sink.frames(frames)
        sink.close()
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        turns = []
        add = app.store.add
        app.store.add = lambda batch: turns.append(len(batch)) or add(batch)
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: app.caught_up and app.frame_list.cursor == len(frames) - 1)
            assert [f.index for f in app.store.frames] == [f.index for f in frames]
            assert turns == [INTAKE_CHUNK] + [1] * (len(frames) - INTAKE_CHUNK)  # then one frame a turn
    run(go())


def test_the_detail_follows_the_tail_at_a_readable_pace_and_shows_a_selected_frame_at_once(monkeypatch):
    """Rebuilding the detail for every new tail frame (15 times a second) took a third of the TUI's time
    under live stress: while the list follows the tail, the detail changes at most every FOLLOW_EVERY_S;
    a frame the user selects shows at once."""
    import sniffer.tui.detail as detail_module

    monkeypatch.setattr(detail_module, "FOLLOW_EVERY_S", 3600.0)

    async def go():
        app, sink, frames = growing_app(50)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            store, detail = app.store, app.detail
            assert detail.frame is store.frames[49]  # the first tail frame shows at once
            sink.frames(frames[50:60])
            app.poll()
            await pilot.pause()
            assert detail.frame is store.frames[49] and detail.due[0] is store.frames[59]  # waits its turn
            await pilot.press("up")
            assert detail.frame is store.frames[58] and detail.due is None  # the user's: at once
            await pilot.press("end")
            assert detail.frame is store.frames[59]
            monkeypatch.setattr(detail_module, "FOLLOW_EVERY_S", 0.2)
            sink.frames(frames[60:70])
            app.poll()
            sink.frames(frames[70:80])
            app.poll()
            assert await until(pilot, lambda: detail.frame is store.frames[79] and detail.due is None)
    run(go())


def test_new_frames_below_a_still_window_and_a_fast_tail(monkeypatch):
    """Issue 11 (CPU): frames arriving below a window that does not follow repaint nothing but the scroll
    extent; a followed tail that moves more than TAIL_ROWS rows between draws is drawn at most every
    TAIL_EVERY_S by the timer (a direct poll draws at once)."""
    import sniffer.tui.vlist as vlist_module

    # a timer's poll (a budget given: the tail drawn at most every TAIL_EVERY_S); a budget no machine runs out of,
    # so a loaded one takes every frame too (10 ms took 73 of 100 under load)
    TIMER = 3600.0

    async def go():
        app, sink, frames = growing_app(100)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            fl = app.frame_list
            await pilot.press("home")
            sink.frames(frames[100:200])
            app.poll(TIMER)
            assert fl.cursor == 0 and fl.virtual_size.height == 200 + fl.header_lines and fl.scroll_offset.y == 0
            await pilot.press("end")
            assert fl.cursor == 199 and fl.follow and app.detail.frame is app.store.frames[199]
            monkeypatch.setattr(vlist_module, "TAIL_EVERY_S", 3600.0)
            sink.frames(frames[200:200 + vlist_module.TAIL_ROWS])  # a slow tail: drawn at once
            app.poll(TIMER)
            last = 199 + vlist_module.TAIL_ROWS
            assert fl.cursor == last
            sink.frames(frames[last + 1:last + 11])  # a fast one, just after a draw: at the next due poll
            app.poll(TIMER)
            assert fl.cursor == last and len(app.store) == last + 11
            sink.frames(frames[last + 11:300])
            app.poll(TIMER)
            assert fl.cursor == last and len(app.store) == 300
            app.poll()
            assert fl.cursor == 299
    run(go())


def test_bookmarks_units_registers_help():
    async def go():
        app = make_app("a510.mcap")
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "m", "down", "down", "m", "home")
            assert app.store.bookmarks == {1, 3}
            await pilot.press("right_square_bracket")
            assert app.frame_list.selected_row == 1
            await pilot.press("right_square_bracket")
            assert app.frame_list.selected_row == 3
            await pilot.press("2")
            await pilot.pause()
            table = app.query_one("#unitstable")
            assert table.row_count == len(app.store.units) == 2
            await pilot.press("3")
            await pilot.pause()
            regs = app.query_one("#regs")
            assert regs.row_count == len(app.store.registers) > 10
            await pilot.press("question_mark")
            assert type(app.screen).__name__ == "HelpScreen"
            await pilot.press("escape")
            assert type(app.screen).__name__ != "HelpScreen"
    run(go())


def test_replay_feed_thread_end_to_end():
    """The real path: a replay decoded on the feed thread while the App polls."""
    from tui_helpers import SIM

    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.sources.files import FileSource
    from sniffer.tui.run import session_app
    from sniffer.tui.sink import TuiSink

    async def go():
        sink = TuiSink()
        session = Session(CaptureSpec(), FileSource(str(SIM / "errors.mcap")), [sink])
        session.open()
        reg = session.registry
        app = session_app(session, sink)
        async with app.run_test(size=SIZE) as pilot:
            for _ in range(200):
                await pilot.pause(0.05)
                if app.caught_up and len(app.store) == app.sink.frames_in:
                    break
            assert app.feed_error is None
            assert len(app.store) == len(replay_frames()[1])
            # the register watch is the decoders' shadow: the writes the decoders recorded on the frames
            shadow = registry_shadow(reg)
            assert {k: rv.raw for k, rv in app.store.registers.items()} == shadow
            await pilot.press("3")
            await pilot.pause()
            assert app.query_one("#regs").row_count == len(shadow) > 100
            await pilot.press("q")
    run(go())


def test_register_watch_of_an_attached_viewer_is_the_decoders_shadow():
    """A viewer attached to a capture gets frame records over a socket, no registry: the records' writes."""
    from sniffer.formats.records import frame_json, loads
    from sniffer.tui.store import frame_from_record

    async def go():
        info, frames, registry = replay_frames("a510.mcap")
        sink = TuiSink()
        sink.start(info)
        sink.frames(frame_from_record(loads(frame_json(f, info.t0_ns)), info.t0_ns) for f in frames)
        sink.close()
        app = SnifferApp(sink, None, clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            assert {k: rv.raw for k, rv in app.store.registers.items()} == registry_shadow(registry)
            await pilot.press("3")
            regs = app.query_one("#regs")
            regs.focus()
            await pilot.press("down")
            await pilot.pause()
            assert regs.row_count == len(app.store.registers) == sum(len(st.holding) for st in registry.states.values())
            watch = app.query_one("#regwatch")
            assert watch.chosen == (1, "holding", 9474)
            assert "Frequency command" in str(app.query_one("#log-label").render())
            cells = [str(c) for c in regs.get_row("1:holding:9474")]
            assert cells[:5] == ["1", "holding", "2502H", "Frequency command", "44.5"] and cells[6] == "4450"
    run(go())


@pytest.mark.parametrize("name", ["errors.mcap"])
def test_mouse_click_selects(name):
    async def go():
        app = make_app(name)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home")
            await pilot.click("#list", offset=(10, 3))
            assert app.frame_list.cursor == 2  # the list's line 3: its first line is the header
            await pilot.click("#list", offset=(10, 0))  # the header selects nothing
            assert app.frame_list.cursor == 2
    run(go())


def test_demo_feed_live_path(tmp_path):
    """The live path for real: the simulated bus on a pty, captured by its own process, viewed over its socket."""
    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: app.caught_up and len(app.store) == app.sink.frames_in, 300)
            assert app.feed_error is None, app.feed_error
            assert len(app.store) > 20 and app.store.units
            assert app.capture_size() and app.capture_size() > 0
            await pilot.press("q")  # the capture has ended: no question

    with demo_viewer(tmp_path, "errors", 1.5) as viewer:
        run(go(viewer.app))
    assert viewer.rc() == 0
    assert [r["raw"] for r in read_frames(str(tmp_path / "d.mcap"))] == [f.raw.hex() for f in viewer.app.store.frames]


def test_quit_stops_a_running_capture(tmp_path):
    async def go(app, capture):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: len(app.store) > 10)
            await pilot.press("q")  # a live capture asks first (issue 11): n, Esc and q go back to it
            for no in ("n", "escape", "q"):
                await pilot.pause(0.05)
                assert type(app.screen).__name__ == "ConfirmQuit", no
                await pilot.press(no)
                await pilot.pause(0.05)
                assert type(app.screen).__name__ != "ConfirmQuit" and app._thread.is_alive(), no
                if no != "q":
                    await pilot.press("q")
            n = len(app.store)
            assert await until(pilot, lambda: len(app.store) > n)  # still capturing after three refusals
            assert capture.returncode is None
            await pilot.press("q", "y")

    with demo_viewer(tmp_path, "default", 60) as viewer:
        run(go(viewer.app, viewer.capture))
    # the capture stopped as on Ctrl-C: exit 0, MCAP closed (no .part left) and holding what the viewer saw
    assert viewer.rc() == 0 and not (tmp_path / "d.mcap.part").exists()
    saved = [r["raw"] for r in read_frames(str(tmp_path / "d.mcap"))]
    shown = [f.raw.hex() for f in viewer.app.store.frames]
    assert len(saved) >= len(shown) > 10 and saved[:len(shown)] == shown


def test_status_bar_shows_the_size_of_a_capture_being_written(tmp_path):
    """While a capture runs its MCAP is NAME.part: the App reports that file's size."""
    from sniffer.tui.sink import TuiSink

    part = tmp_path / "cap.mcap.part"
    part.write_bytes(b"x" * 1234)
    app = SnifferApp(TuiSink(), None, capture_path=str(tmp_path / "cap.mcap"))
    assert app.capture_size() == 1234
    (tmp_path / "cap.mcap").write_bytes(b"y" * 10)  # renamed into place at the end
    part.unlink()
    assert app.capture_size() == 10


def test_an_idle_view_redraws_nothing():
    """Issue 11: an idle replay took 17-20 % of a core.  Once every frame is in, the polls change no
    widget: the status bar is set again only when its text changes, the tables only when the store
    or the tab does (benchmarks measure the CPU; this holds the cause)."""
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("2")  # the units table, rebuilt by the polls while it is shown
            for _ in range(10):
                app.poll()
            await pilot.pause()
            calls = {"status": 0, "tables": 0}
            status_update, refresh_tables = app.status.update, app.refresh_tables

            def counted_status(*a, **k):
                calls["status"] += 1
                return status_update(*a, **k)

            def counted_tables():
                calls["tables"] += 1
                return refresh_tables()

            app.status.update, app.refresh_tables = counted_status, counted_tables
            for _ in range(60):  # four seconds of polls at 15 Hz
                app.poll()
            assert calls == {"status": 0, "tables": 0}
            await pilot.press("3")  # another tab: its table is built by the next polls that may
            await pilot.pause()
            for _ in range(10):
                app.poll()
            assert calls["tables"] >= 1
            calls["tables"] = 0
            for _ in range(30):  # and then it rests again
                app.poll()
            assert calls == {"status": 0, "tables": 0}
    run(go())


def test_keys_typed_right_after_slash_are_filter_text():
    """Issue 11: under load, keys typed right after '/' ran as commands ('q' quit a live capture).  The
    driver delivers a fast typist's keys as one burst of events: all of them reach the filter bar."""
    from textual import events

    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            for key, char in [("slash", "/")] + [(c, c) for c in "quality"] + [("enter", "\r")]:
                event = events.Key(key, char)  # as the driver sends them (Pilot.press, without its waits)
                event.set_sender(app)
                app._driver.send_message(event)  # one burst, nothing awaited in between
            await pilot.pause()
            await pilot.pause()
            assert app.is_running and app.return_code is None
            assert filter_words(app) == ["quality"]
            assert app.focused is app.frame_list
    run(go())


def filter_words(app) -> list[str]:
    from sniffer.tui.filters import filter_expr

    return filter_expr(app.store.filter).split()


def test_a_slash_typed_in_the_filter_is_text():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("/", "a", "/", "b")
            assert app.filter_bar.value == "a/b" and app.focused is app.filter_bar
    run(go())


def test_ended_shows_only_once_every_frame_is_in_view():
    """Issue 11: `[ended]` showed while a replay was still loading into the view."""
    from sniffer.tui.status import status_text

    async def go():
        _, _, registry = replay_frames("errors.mcap")
        # the view takes 20 frames a poll, and only the polls this test makes (no timer: a slow poll_hz)
        app = SnifferApp(filled_sink("errors.mcap"), None, source_label="errors.mcap", registry=registry,
                         clock=lambda: 0.0, poll_hz=0.001, max_batch=20)
        async with app.run_test(size=SIZE):
            app.poll()
            assert app.sink.closed.is_set() and app.sink.backlog > 0
            text = status_text(app).plain
            assert "[loading:" in text and "[ended]" not in text
            while app.sink.backlog:
                app.poll()
            assert "[ended]" in status_text(app).plain
    run(go())


def test_drive_faults_have_their_own_colour_count_and_are_found_by_n():
    """Issue 11: a frame reporting a fault code or alarm is a problem of its own: coloured apart from CRC
    errors and exceptions, found by n / errors-only, counted per unit in Units, its text in the detail."""
    from helpers import bursts, fr, run_events

    from sniffer.line import LineSettings
    from sniffer.tui.framelist import S_ERROR, S_EXC, S_FAULT, row_style
    from sniffer.tui.store import F_FAULT, FrameStore, frame_flags

    line = LineSettings(19200, "E", 1)
    frames = run_events(bursts([fr("010300000001"), fr("0103020005"),       # a plain read
                                fr("010325210001"), fr("0103020015"),       # fault code 21
                                fr("010300000001"), fr("0183 02".replace(" ", ""))], line),
                        line, devices={1: "a510"})
    fault = frames[3]
    assert frame_flags(fault) & F_FAULT and row_style(frame_flags(fault)) is S_FAULT
    assert len({S_ERROR, S_EXC, S_FAULT}) == 3
    store = FrameStore(frames[0].t_ns)
    store.add(frames)
    assert store.units[1].faults == 1 and store.units[1].exceptions == 1
    assert 3 in list(store.problems)
    detail = next(a.detail for a in fault.annotations if a.code == "model.fault")
    assert detail == "fault: External Fault 05 (Error description (fault code))"  # A510 code 21


def test_a_unit_seen_only_in_crc_bad_frames_is_marked_a_ghost():
    """Issue 11: ghost units from corrupted frames are marked as such in Units."""
    from helpers import bursts, fr, run_events

    from sniffer.line import LineSettings
    from sniffer.tui.store import FrameStore
    from sniffer.tui.units import unit_cells

    line = LineSettings(19200, "E", 1)
    bad = bytearray(bytes.fromhex(fr("090300000001")))
    bad[-1] ^= 0xFF  # unit 9 only in a frame with a bad CRC
    frames = run_events(bursts([fr("010300000001"), fr("0103020005"), bad.hex()], line), line)
    store = FrameStore(frames[0].t_ns)
    store.add(frames)
    assert unit_cells(store.units[9], 0)[1] == "ghost? (CRC-bad frames only)"
    assert "ghost" not in unit_cells(store.units[1], 0)[1]


def test_the_status_bar_says_when_the_view_stops_following_the_tail(tmp_path):
    """Issue 11: when the view stops following new frames (a move up, a filter), the screen says so."""
    from sniffer.tui.status import status_text

    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: len(app.store) > 10)
            assert "not following" not in status_text(app).plain
            await pilot.press("home")
            assert "[not following the tail: End]" in status_text(app).plain
            await pilot.press("end")
            assert "not following" not in status_text(app).plain
            await pilot.press("q", "y")

    with demo_viewer(tmp_path, "default", 60) as viewer:
        run(go(viewer.app))


def test_the_apps_process_is_readied_for_keys():
    """Issue 11: run.py readies the App's process: a feed thread holds the interpreter at most UI_SWITCH_S
    at a time, the imports are frozen out of the collector's walks, young collections come GC_YOUNG objects
    apart (in a process of its own: these are process-wide)."""
    import subprocess
    import sys

    code = ("import gc, sys; from sniffer.tui.run import _ready_interpreter, UI_SWITCH_S, GC_YOUNG; "
            "_ready_interpreter(); print(sys.getswitchinterval() <= UI_SWITCH_S, "
            "gc.get_threshold()[0] == GC_YOUNG, gc.get_freeze_count() > 0)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "True"]


def test_verdicts_tab_shows_the_findings_and_goes_to_their_frames(tmp_path):
    """7: sniffer diagnose's findings on the frames taken in so far, the same as the command's; Enter on one goes
    to its first frame; a viewer that takes more frames sees the verdicts follow."""
    from sniffer.cli import main
    from sniffer.diagnose import Diagnosis

    cap = str(tmp_path / "silent.mcap")
    assert main(["simulate", "--duration", "8", "--fault", "unit_silent:5", "--out", cap]) == 0
    info, frames, registry = replay_frames(cap)
    engine = Diagnosis()
    for f in frames:
        engine.frame(f)
    expected = [(f.kind, f.unit) for f in engine.findings()]
    assert ("unit_silent", 5) in expected
    sink = TuiSink()
    sink.start(info)
    half = len(frames) // 8
    sink.frames(frames[:half])

    async def go():
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0, poll_hz=0.001)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            assert len(app.store) == half
            await pilot.press("7")
            await pilot.pause()
            pane = app.query_one("#verdictspane")
            early = [(f.kind, f.unit) for f in pane.findings]
            sink.frames(frames[half:])  # the capture goes on: more frames, the verdicts follow
            sink.close()
            app.poll()
            app.refresh_tables()
            await pilot.pause()
            assert [(f.kind, f.unit) for f in pane.findings] == expected != early
            first = pane.findings[0]
            assert (first.kind, first.unit) == ("unit_silent", 5)
            assert "unit_silent" in str(pane.list.get_option_at_index(0).prompt)
            await pilot.press("enter")
            await pilot.pause()
            assert app.tabs.active == "frames"
            assert app.store.frame(app.frame_list.selected_row).index == first.frames[0]
    run(go())


def test_verdicts_of_a_live_capture(tmp_path):
    """`sniffer demo --fault unit_silent:5` under the TUI: the capture runs in its own process (the fault goes
    with it), the viewer gets records over the socket, and its Verdicts tab names the silent unit."""
    async def go(app):
        async with app.run_test(size=SIZE) as pilot:
            assert await until(pilot, lambda: app.caught_up and len(app.store) == app.sink.frames_in, 300)
            await pilot.press("7")
            await pilot.pause()
            app.refresh_tables()
            await pilot.pause()
            pane = app.query_one("#verdictspane")
            assert ("unit_silent", 5) in [(f.kind, f.unit) for f in pane.findings]
            await pilot.press("q")

    with demo_viewer(tmp_path, "default", 3.0, faults=("unit_silent:5",)) as viewer:
        run(go(viewer.app))
    assert viewer.rc() == 0
