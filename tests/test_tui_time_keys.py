"""The time keys under Textual's Pilot: t (time base), T (time reference), g (go to), the Δt column, the
status bar's word when the view stops following the tail, and the 80x24 layout."""

import asyncio
import bisect
import dataclasses
from datetime import datetime, timedelta, timezone

from textual import events
from textual.widgets import Tree
from tui_helpers import replay_frames, screen_text

from sniffer.tui.app import SnifferApp
from sniffer.tui.framelist import MIN_SUMMARY, summary_text
from sniffer.tui.sink import TuiSink
from sniffer.tui.timebase import REF, REL, WALL, delta_text

SIZE = (140, 45)
S = 1_000_000_000
PLUS2 = timezone(timedelta(hours=2))
START = datetime(2024, 5, 1, 19, 22, tzinfo=PLUS2)  # errors.mcap's t0_ns is 0: frame times are since the start
ANCHOR = int((START - datetime(1970, 1, 1, tzinfo=timezone.utc)).total_seconds()) * S
HINT = "[not following the tail: End]"


def app_of(name="errors.mcap", anchor: int = ANCHOR, closed: bool = True, frames=None) -> SnifferApp:
    """The App over a replay's frames; `anchor` the capture's wall-clock start (0: unknown), `closed`
    False: a capture still running (frames may arrive)."""
    info, all_frames, registry = replay_frames(name)
    sink = TuiSink()
    sink.start(dataclasses.replace(info, wall_anchor_ns=anchor))
    sink.frames(all_frames if frames is None else frames)
    if closed:
        sink.close()
    app = SnifferApp(sink, None, source_label=name, registry=registry, clock=lambda: 0.0)
    app.store.time.tz = PLUS2  # the viewer's zone, fixed for the test
    return app


async def loaded(app, pilot):
    app.poll()
    await pilot.pause()
    return app


def notes(app) -> list[tuple[str, str]]:
    """Record the App's notifications as (message, severity) from now on."""
    seen = []
    notify = app.notify

    def record(message, **kw):
        seen.append((str(message), kw.get("severity", "information")))
        return notify(message, **kw)

    app.notify = record
    return seen


def row_text(app, y: int) -> str:
    """The list's row `y` (from the top of the visible rows, under the header) as drawn."""
    return app.frame_list.render_line(y + 1).text


def header(app) -> str:
    """The list's header line as drawn."""
    return app.frame_list.render_line(0).text


def detail_time(app) -> list[str]:
    root = app.detail.query_one(Tree).root
    node = next(n for n in root.children if str(n.label) == "time")
    return [str(c.label) for c in node.children]


def run(coro):
    asyncio.run(coro)


def test_t_cycles_the_time_base_and_header_list_and_detail_say_which():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home")
            f = app.store.frames[0]
            assert "time (s)" in header(app) and "time: since the capture's start" in header(app)
            assert row_text(app, 0)[4:].lstrip().startswith(app.store.time.text(f.t_ns))
            assert "since the start" in str(app.detail.query_one(Tree).root.label)
            await pilot.press("t")
            assert app.store.time.mode == WALL
            wall = (START + timedelta(microseconds=f.t_ns // 1000)).strftime("%H:%M:%S.%f")[:12]
            assert "wall clock" in header(app) and "2024-05-01 UTC+02:00" in header(app)
            assert row_text(app, 0)[4:].startswith(wall)
            assert "(wall clock)" in str(app.detail.query_one(Tree).root.label)
            assert f"wall clock: 2024-05-01 {wall}" in detail_time(app)[1]
            await pilot.press("t")  # no reference set: back to since the start
            assert app.store.time.mode == REL and "time (s)" in header(app)
    run(go())


def test_t_without_a_wall_clock_or_reference_says_there_is_only_relative_time():
    async def go():
        app = app_of(anchor=0)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            seen = notes(app)
            await pilot.press("t")
            assert app.store.time.mode == REL
            assert len(seen) == 1 and "no wall-clock start" in seen[0][0]
            assert "wall clock: not known for this capture" in detail_time(app)
    run(go())


def test_T_sets_moves_and_clears_the_time_reference():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down", "down", "T")
            tb, ref = app.store.time, app.store.frames[3]
            assert (tb.mode, tb.ref_row, tb.ref_index) == (REF, 3, ref.index)
            assert f"from #{ref.index}" in header(app) and f"time: from the reference #{ref.index}" in header(app)
            assert "*REF*" in row_text(app, 3)
            later, earlier = app.store.frames[5], app.store.frames[1]
            assert tb.text(later.t_ns).startswith("+") and tb.text(later.t_ns) in row_text(app, 5)
            assert tb.text(earlier.t_ns).startswith("-") and tb.text(earlier.t_ns) in row_text(app, 1)
            assert "from the reference" in str(app.detail.query_one(Tree).root.label)
            await pilot.press("t", "t", "t")  # since the start -> wall clock -> from the reference again
            assert tb.mode == REF
            await pilot.press("down", "T")  # another frame: the reference moves
            assert tb.ref_row == 4 and "*REF*" in row_text(app, 4) and "*REF*" not in row_text(app, 3)
            await pilot.press("T")  # on the reference again: cleared
            assert tb.ref_row is None and tb.mode == REL
            assert "*REF*" not in screen_text(app) and "time (s)" in header(app)
    run(go())


def test_delta_t_is_the_time_since_the_previous_frame_shown():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down", "u")  # unit 2 only: the frames between are hidden
            store = app.store
            await pilot.press("home")
            view = store.view
            i = next(i for i in range(1, 30) if view[i] - view[i - 1] > 1)  # frames hidden between the two
            dt = delta_text(store.t_ns[view[i]] - store.t_ns[view[i - 1]])
            head = header(app)
            end = head.index("Δt") + 2
            assert row_text(app, i)[:end].endswith(dt)
            assert row_text(app, 0)[:end].endswith(" " * 8)  # the first shown has none
            await pilot.press(*["down"] * i)
            assert f"Δt: {dt} after #{store.frames[view[i - 1]].index} (the previous frame shown)" in detail_time(app)
    run(go())


def _first_at(app, t_ns: int) -> int:
    return bisect.bisect_left(app.store.t_ns, t_ns)


GOTO_FORMS = [  # what is typed, the row it lands on
    ("17", lambda app: app.store.row_of[17]),
    ("#120", lambda app: app.store.row_of[120]),
    ("2.5s", lambda app: _first_at(app, int(2.5 * S))),
    ("2.5", lambda app: _first_at(app, int(2.5 * S))),
    ("350ms", lambda app: _first_at(app, 350_000_000)),
    ("19:22:04.125", lambda app: _first_at(app, 4_125_000_000)),
    ("2024-05-01 19:22:01", lambda app: _first_at(app, S)),
]


def test_goto_each_form():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            seen = notes(app)
            for typed, expect in GOTO_FORMS:
                await pilot.press("end", "g")
                assert app.focused is app.query_one("#gotobar")
                await pilot.press(*["space" if c == " " else c for c in typed], "enter")
                row = expect(app)
                assert 0 < row < len(app.store) - 1
                assert app.frame_list.selected_row == row and not app.frame_list.follow, typed
                assert app.detail.frame.index == app.store.frames[row].index
                assert not app.query_one("#gotobar").shown and app.focused is app.frame_list
            assert seen == []
    run(go())


def test_goto_from_the_reference_and_from_another_tab():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", *["down"] * 10, "T", "2", "g", *"-50ms", "enter")
            want = _first_at(app, app.store.t_ns[10] - 50_000_000)
            assert app.tabs.active == "frames" and app.frame_list.selected_row == want < 10
    run(go())


def test_goto_a_frame_the_filter_hides_lands_on_the_nearest_shown_and_says_so():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down", "u")  # unit 2 only
            hidden = next(r for r in range(100, len(app.store)) if app.store.pos_of_row(r) is None)
            index = app.store.frames[hidden].index
            seen = notes(app)
            await pilot.press("g", *str(index), "enter")
            row = app.frame_list.selected_row
            assert app.store.frames[row].unit == 2 and abs(row - hidden) < 20
            assert seen == [(f"#{index} is hidden by the filter: at #{app.store.frames[row].index}, "
                             "the nearest shown frame", "warning")]
    run(go())


GOTO_ERRORS = [("abc", "is not a frame number or a time"), ("99999", "no frame #99999 here"),
               ("99s", "no frame at or after 99.000000s since the start"), ("25:61", "not a wall-clock time")]


def test_goto_bad_input_is_one_error_and_the_bar_stays_to_fix_it():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home")
            bar = app.query_one("#gotobar")
            for typed, says in GOTO_ERRORS:
                seen = notes(app)
                await pilot.press("g", *typed, "enter")
                assert len(seen) == 1 and seen[0][1] == "error" and says in seen[0][0], seen
                assert bar.shown and bar.value == typed and app.focused is bar
                assert app.frame_list.selected_row == 0 and app.is_running
                await pilot.press("escape")
                assert not bar.shown and app.focused is app.frame_list
            await pilot.press("g", "enter")  # nothing typed: just closes
            assert not bar.shown and len(seen) == 1
    run(go())


def test_goto_a_wall_clock_time_in_a_capture_without_one_says_so():
    async def go():
        app = app_of(anchor=0)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            seen = notes(app)
            await pilot.press("g", *"19:22:01", "enter")
            assert len(seen) == 1 and "no wall-clock start" in seen[0][0] and seen[0][1] == "error"
    run(go())


def test_keys_typed_right_after_g_go_to_the_bar():
    """As after '/': a burst of keys right after g is the target, never commands ('q' would quit)."""
    async def burst(app, pilot, keys):
        for key in keys:
            event = events.Key(key, "\r" if key == "enter" else key)  # as the driver sends them, nothing awaited
            event.set_sender(app)
            app._driver.send_message(event)
        await pilot.pause()
        await pilot.pause()

    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await burst(app, pilot, ["g", "1", "7", "enter"])
            assert app.selected_frame.index == 17
            seen = notes(app)
            await burst(app, pilot, ["g", "q", "enter"])
            assert app.is_running and app.query_one("#gotobar").value == "q" and seen[0][1] == "error"
    run(go())


def test_g_and_slash_typed_in_a_bar_are_text():
    async def go():
        app = app_of()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("/", *"reg")
            assert app.filter_bar.value == "reg" and not app.query_one("#gotobar").shown
            await pilot.press("escape", "g", "slash")
            assert app.query_one("#gotobar").value == "/" and not app.filter_bar.has_class("shown")
    run(go())


def status_line(app) -> str:
    return screen_text(app).splitlines()[-2]  # the line above the footer


STOPS_FOLLOWING = [(["up"], HINT), (["home"], HINT), (["e"], HINT), (["u"], HINT),
                   (["slash", *"u:1", "enter"], HINT), (["g", *"#5", "enter"], HINT), (["space"], "PAUSED")]


def test_the_screen_says_when_the_view_stops_following_the_tail():
    """Issue 11: a filter, a pause, a move up or a go-to stops following new frames: the status bar says
    so, at 80x24 too, and End (space for a pause) follows again."""
    async def go():
        info, frames, _ = replay_frames()
        app = app_of(closed=False, frames=frames[:200])  # a capture still running: more may come
        more = iter(range(200, len(frames), 10))
        async with app.run_test(size=(80, 24)) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "end", "n")  # n from the tail finds nothing further: still following
            assert app.frame_list.follow and HINT not in status_line(app)
            for keys, word in STOPS_FOLLOWING:
                await pilot.press(*keys)
                app.poll()
                await pilot.pause()
                assert word in status_line(app), (keys, status_line(app))
                cursor, start = app.frame_list.cursor, next(more)
                app.sink.frames(frames[start:start + 10])
                app.poll()
                await pilot.pause()
                assert app.frame_list.cursor == cursor, keys  # not following: the new frames arrive below
                await pilot.press("space" if word == "PAUSED" else "end")
                app.poll()
                await pilot.pause()
                assert app.frame_list.follow and HINT not in status_line(app), keys
                assert "PAUSED" not in status_line(app)
                await pilot.press("c", "end")  # no filter for the next case
    run(go())


def test_at_80x24_every_row_shows_its_summary():
    """Issue 11: at 80x24 the frame list's summary fell off the screen."""
    async def go():
        app = app_of()
        async with app.run_test(size=(80, 24)) as pilot:
            await loaded(app, pilot)
            for keys in ([], ["t"], ["t", "T"], ["e"]):  # since the start, wall clock (wider), reference, filtered
                await pilot.press(*keys)
                lines = screen_text(app).splitlines()
                head = next(i for i, line in enumerate(lines) if "summary" in line)
                at = lines[head].index("summary")
                assert 80 - at >= MIN_SUMMARY, keys
                top, fl = round(app.frame_list.scroll_offset.y), app.frame_list
                rows = app.store.view[top:top + fl.rows_shown]
                assert len(rows) >= 8
                for row, line in zip(rows, lines[head + 1:]):
                    summary, shown = summary_text(app.store.frames[row]), line[at:78].rstrip().rstrip("…")
                    assert summary.startswith(shown) and len(shown) >= min(MIN_SUMMARY - 1, len(summary)), keys
            status = lines[-2]
            assert "432 fr" in status and "filter: errors" in status and "[ended]" in status
    run(go())


def test_at_80x24_units_keep_the_unit_when_scrolled_to_the_latencies():
    async def go():
        app = app_of()
        async with app.run_test(size=(80, 24)) as pilot:
            await loaded(app, pilot)
            await pilot.press("2")
            table = app.query_one("#unitstable")
            table.scroll_to(x=table.max_scroll_x, animate=False)  # as far as → goes
            await pilot.pause()
            lines = screen_text(app).splitlines()
            assert lines[2].split()[0] == "unit" and "lat max" in lines[2]
    run(go())


def test_the_time_keys_are_in_the_help_and_the_docs():
    from pathlib import Path

    from sniffer.tui.app import HELP

    keys = {b.key for b in SnifferApp.BINDINGS if b.action in ("time_base", "time_reference", "goto_bar")}
    assert keys == {"t", "T", "g"}
    page = (Path(__file__).resolve().parent.parent / "docs" / "tui.md").read_text()
    tui = page[page.index("## The tabs and their keys"):page.index("## What it looks like")]
    for key in keys:
        assert f"[b]{key}[/b]" in HELP and f"`{key}`" in tui, key
