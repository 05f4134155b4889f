"""The plot tab and the change log under Textual's Pilot, over a deterministic replay (a510: the drives ramp)."""

from pathlib import Path

from test_tui import SIZE, loaded, run
from test_tui import make_app as _make_app
from test_tui_history import CURRENT, FREQ_OUT, carried, changes_of
from tui_helpers import replay_frames

from sniffer.tui.app import HELP, SnifferApp
from sniffer.tui.changelog import ChangeLog
from sniffer.tui.plot import PlotView
from sniffer.tui.registers import RegisterWatch
from sniffer.tui.sink import TuiSink

STATUS_WORD = 0x2520  # A510 state signal: a handful of changes in a510.mcap


def make_app(name="a510.mcap") -> SnifferApp:
    return _make_app(name)


async def highlight(pilot, key) -> None:
    """In the Registers tab, move the table's cursor down to register `key` (as a user would)."""
    app = pilot.app
    regs = app.query_one("#regs")
    target = regs.get_row_index(f"{key[0]}:{key[1]}:{key[2]}")
    while regs.cursor_row != target:
        await pilot.press("down" if regs.cursor_row < target else "up")
    await pilot.pause()
    assert app.query_one(RegisterWatch).chosen == key


def plot_text(view: PlotView) -> list[str]:
    return ["".join(t for t, _ in line) for line in view.image.lines]


def test_two_registers_on_the_plot_zoom_and_a_click_goes_to_the_nearest_sample():
    async def go():
        app = make_app()
        freq, current = (1, "holding", FREQ_OUT), (2, "holding", CURRENT)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("3")
            assert app.focused is app.query_one("#regs")  # the Registers tab keeps the keys when opened
            await highlight(pilot, freq)
            await pilot.press("a")
            await highlight(pilot, current)
            await pilot.press("a")
            await pilot.press("5")
            await pilot.pause()
            view = app.query_one("#plotview", PlotView)
            assert app.focused is view and view.plots.keys == [freq, current]
            legend = app.query_one("#legend")
            rows = [[str(c) for c in legend.get_row_at(i)] for i in range(legend.row_count)]
            assert [r[1:4] for r in rows] == [["1", "2524H Output frequency", "left Hz"],
                                               ["2", "2527H Output current", "right A"]]
            text = plot_text(view)
            assert "Hz" in text[0] and text[0].rstrip().endswith("A")
            colours = {st for line in view.image.lines for _, st in line}
            assert {view.plots.colours[freq], view.plots.colours[current]} <= colours  # both drawn
            lo, hi = view.time_range()
            assert (lo, hi) == (app.store.t0_ns, app.store.last_t_ns) and view.window.following
            labels = text[-1]
            await pilot.press("plus")
            lo2, hi2 = view.time_range()
            assert hi2 - lo2 == (hi - lo) / 2 and hi2 == hi  # following: zoomed on the tail
            assert plot_text(view)[-1] != labels
            await pilot.press("left")
            lo3, hi3 = view.time_range()
            assert (hi3 - lo3, hi3) == (hi2 - lo2, hi2 - (hi2 - lo2) / 4) and not view.window.following
            assert plot_text(view)[-1].split()[0] != labels.split()[0]
            await pilot.press("0")
            assert view.time_range() == (lo, hi) and view.window.following

            # a click on a cell the current is drawn in: its sample nearest that column's time
            img = view.image
            i = [tr.key for tr in view.traces].index(current)
            x, y = next((img.x0 + c, img.top + s[0]) for c, s in enumerate(img.spans[i])
                        if s is not None and c > img.cols // 3 and img.trace_at(img.x0 + c, img.top + s[0]) == i)
            t = img.time_at(x)
            expected = min(carried(replay_frames("a510.mcap")[1], 2, CURRENT), key=lambda s: abs(s[0] - t))[1]
            await pilot.click("#plotview", offset=(x, y))
            await pilot.pause()
            assert app.tabs.active == "frames" and app.focused is app.frame_list
            f = app.selected_frame
            assert f.index == expected and f.unit == 2 and any(w[1] <= CURRENT < w[1] + len(w[2]) for w in f.writes)
            await pilot.press("5")
            assert view.plots.chosen_key == current and view.cursor_ns == t
            await pilot.press("d")  # the chosen register goes
            await pilot.pause()
            assert view.plots.keys == [freq] and legend.row_count == 1
    run(go())


def test_keys_move_the_cursor_and_enter_goes_to_the_frame():
    async def go():
        app = make_app()
        freq = (1, "holding", FREQ_OUT)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("3")
            await highlight(pilot, freq)
            await pilot.press("a", "5")
            view = app.query_one("#plotview", PlotView)
            await pilot.press("full_stop")  # the cursor appears in the middle
            mid = view.cursor_ns
            await pilot.press(*["comma"] * 10)
            img = view.image
            assert view.cursor_ns < mid and img.column_of(view.cursor_ns) == img.column_of(mid) - 10
            t = view.cursor_ns
            expected = min(carried(replay_frames("a510.mcap")[1], 1, FREQ_OUT), key=lambda s: abs(s[0] - t))[1]
            info = "".join(s.text for s in view.render_line(view.size.height - 1))  # the line under the plot
            assert f"at #{expected} " in info and "cursor " in info
            await pilot.press("enter")
            await pilot.pause()
            assert app.tabs.active == "frames" and app.selected_frame.index == expected
    run(go())


def test_change_log_lists_the_changes_and_enter_goes_to_one():
    async def go():
        app = make_app()
        key = (1, "holding", STATUS_WORD)
        frames = replay_frames("a510.mcap")[1]
        truth = changes_of(carried(frames, 1, STATUS_WORD))
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("3")
            await highlight(pilot, key)
            log = app.query_one("#changelog", ChangeLog)
            assert 3 <= log.count() == len(truth) < app.store.registers[key].history.seen
            assert [log.change(i)[1] for i in range(log.count())] == [ix for _, ix, _, _ in truth]
            first = "".join(s.text for s in log.render_line(0))
            assert f"#{truth[0][1]}" in first and "first → " in first
            line = "".join(s.text for s in log.render_line(1))
            assert f"#{truth[1][1]} " in line and f"{truth[1][2]} → {truth[1][3]}" in line
            label = str(app.query_one("#log-label").render())
            assert f"{len(truth) - 1} changes, {len(carried(frames, 1, STATUS_WORD))} samples" in label
            await pilot.press("enter")  # into the change log (its cursor on the latest change)
            assert app.focused is log and log.cursor == len(truth) - 1
            await pilot.press("escape")
            assert app.focused is app.query_one("#regs")
            await pilot.press("enter", "home", "down")
            await pilot.press("enter")
            await pilot.pause()
            assert app.tabs.active == "frames" and app.selected_frame.index == truth[1][1]
            await pilot.press("3")  # the tab as it was left; a click selects a change, a second one goes to it
            await pilot.click("#changelog", offset=(4, 2))
            assert app.tabs.active == "registers" and log.cursor == 2
            await pilot.click("#changelog", offset=(4, 2))
            await pilot.pause()
            assert app.tabs.active == "frames" and app.selected_frame.index == truth[2][1]
    run(go())


def test_going_to_a_frame_the_filter_hides_says_so():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("slash", *"u:2", "enter")  # unit 1's frames are filtered out
            assert app.store.filter.units == {2}
            await pilot.press("3")
            await highlight(pilot, (1, "holding", STATUS_WORD))
            await pilot.press("enter", "enter")  # into the change log, then its latest change
            await pilot.pause()
            assert app.tabs.active == "registers"
            assert any("is not in the list: filtered out" in n.message for n in app._notifications)
    run(go())


def test_the_plot_follows_the_tail_until_zoomed_into_the_past():
    async def go():
        info, frames, registry = replay_frames("a510.mcap")
        sink = TuiSink()
        sink.start(info)
        half = len(frames) // 2
        sink.frames(frames[:half])
        app = SnifferApp(sink, None, registry=registry, clock=lambda: 0.0)
        freq = (1, "holding", FREQ_OUT)
        async with app.run_test(size=SIZE) as pilot:
            app.poll()  # half the capture so far (the feed goes on)
            await pilot.pause()
            await pilot.press("3")
            await highlight(pilot, freq)
            await pilot.press("a", "5", "plus")  # following: the latest half of what came so far
            view = app.query_one("#plotview", PlotView)
            lo, hi = view.time_range()
            assert hi == frames[half - 1].t_ns and view.window.following
            sink.frames(frames[half:half + 100])
            app.poll()
            app.refresh_tables()
            assert view.time_range() == (frames[half + 99].t_ns - (hi - lo), frames[half + 99].t_ns)
            assert view.image.hi == frames[half + 99].t_ns  # drawn again for the new frames
            await pilot.press("left")  # into the past: the window stays where it is
            fixed = view.time_range()
            sink.frames(frames[half + 100:])
            app.poll()
            app.refresh_tables()
            assert view.time_range() == fixed and not view.window.following
            await pilot.press("0")
            assert view.time_range() == (info.t0_ns, frames[-1].t_ns)
    run(go())


def test_an_empty_plot_says_what_to_do_and_the_plot_holds_eight_registers():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("5")
            view = app.query_one("#plotview", PlotView)
            assert view.image is None and "press a on a register" in "".join(s.text for s in view.render_line(0))
            await pilot.press("enter")  # nothing plotted: a message, no jump
            await pilot.pause()
            assert app.tabs.active == "plot"
            await pilot.press("3")
            for _ in range(9):
                await pilot.press("a", "down")
            await pilot.pause()
            keys = sorted(app.store.registers)
            assert view.plots.keys == keys[:8]  # a ninth is refused (one colour each)
            assert len(set(view.plots.colours.values())) == 8
            await pilot.press("up", "up", "a")  # a again: off the plot
            assert keys[7] not in view.plots and len(view.plots) == 7
            await pilot.press("down", "a")  # now there is room for the ninth
            assert view.plots.keys == keys[:7] + [keys[8]]
    run(go())


def test_help_and_docs_name_the_plot_keys():
    page = (Path(__file__).resolve().parent.parent / "docs" / "tui.md").read_text()
    for key in ("5", "a", "+ -", "0", "d", ", .", "← →", "↑ ↓", "Enter", "Esc"):
        assert f"[b]{key}[/b]" in HELP, key
    for key in ("`5`", "`a`", "`+`/`-`", "`0`", "`,`/`.`", "`d`"):
        assert key in page, key
    bound = {b.key for cls in (PlotView, RegisterWatch, ChangeLog) for b in cls.BINDINGS}
    assert {"plus,equals_sign", "minus", "0", "comma", "full_stop", "a", "d,delete", "enter", "escape"} <= bound
