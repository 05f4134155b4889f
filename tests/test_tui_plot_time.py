"""The plots and the change log in the frame list's time base (t: since the start, wall clock, from a
reference frame), as ticks (synthetic times) and under Textual's Pilot (a510's ramps)."""

import asyncio
import dataclasses
import re

from test_tui_history import FREQ_OUT
from test_tui_plot import highlight, plot_text
from test_tui_time_keys import ANCHOR, PLUS2, S, START
from tui_helpers import replay_frames

from sniffer.tui.app import SnifferApp
from sniffer.tui.changelog import ChangeLog
from sniffer.tui.plot import PlotView
from sniffer.tui.plotaxis import time_ticks
from sniffer.tui.sink import TuiSink
from sniffer.tui.timebase import REF, REL, WALL, TimeBase

SIZE = (140, 45)


def test_ticks_since_the_start_from_a_reference_and_on_the_wall_clock():
    base = TimeBase(t0_ns=5 * S, wall_anchor_ns=ANCHOR + 250_000_000, tz=PLUS2)  # starts at 19:22:00.250
    ticks, unit = time_ticks(base, 5 * S, 15 * S, 5)
    assert unit == "s" and [t for t, _ in ticks] == [5 * S + k * 2 * S for k in range(6)]
    assert [text for _, text in ticks] == ["0", "2", "4", "6", "8", "10"]

    base.ref_row, base.ref_t_ns, base.ref_index, base.mode = 3, 9 * S, 41, REF
    ticks, unit = time_ticks(base, 5 * S, 15 * S, 5)
    assert unit == "s from #41" and [text for _, text in ticks] == ["-4", "-2", "0", "2", "4", "6"]
    assert dict(ticks)[9 * S] == "0"  # the reference frame is at 0

    base.mode = WALL  # ticks on whole wall-clock seconds, not on whole seconds since the start
    ticks, unit = time_ticks(base, 5 * S, 15 * S, 5)
    assert unit == "UTC+02:00"  # the zone's name (a fixed offset's, here)
    assert [text for _, text in ticks] == ["19:22:02", "19:22:04", "19:22:06", "19:22:08", "19:22:10"]
    for t, text in ticks:  # each tick at the capture time whose wall clock it names
        assert base.wall_datetime(int(t)) == START.replace(second=int(text[-2:]))
    ticks, _ = time_ticks(base, 5 * S, 5 * S + 3600 * S, 4)  # an hour: ticks on local quarter hours
    assert [text for _, text in ticks] == ["19:30:00", "19:45:00", "20:00:00", "20:15:00"]
    ticks, _ = time_ticks(base, 6 * S, 6 * S + 40_000_000, 4)  # 40 ms: minutes, seconds and milliseconds
    assert [text for _, text in ticks] == ["22:01.250", "22:01.260", "22:01.270", "22:01.280", "22:01.290"]


def test_the_plot_and_the_change_log_follow_the_time_base():
    async def go():
        info, frames, registry = replay_frames("a510.mcap")
        sink = TuiSink()
        sink.start(dataclasses.replace(info, wall_anchor_ns=ANCHOR))
        sink.frames(frames)
        sink.close()
        app = SnifferApp(sink, None, source_label="a510.mcap", registry=registry, clock=lambda: 0.0)
        app.store.time.tz = PLUS2
        async with app.run_test(size=SIZE) as pilot:
            app.poll()
            await pilot.pause()
            freq = (1, "holding", FREQ_OUT)
            await pilot.press("3")
            await highlight(pilot, freq)
            log = app.query_one(ChangeLog)
            first_change = str(log.line_text(0))
            assert first_change.split()[0].replace(".", "").isdigit()  # seconds since the start
            await pilot.press("a", "5")
            await pilot.pause()
            view = app.query_one("#plotview", PlotView)
            axis = plot_text(view)[-1]
            assert axis.rstrip().endswith(" s") and ":" not in axis
            assert re.match(r"0\.000000\.\.\d+\.\d{6} s", view.info()), view.info()

            await pilot.press("t")  # the wall clock
            await pilot.pause(0.3)
            assert app.store.time.mode == WALL
            axis = plot_text(view)[-1]
            assert "19:22:" in axis and not axis.rstrip().endswith(" s"), axis
            assert re.match(r"19:22:00\.000\.\.19:2\d:\d\d\.\d{3} UTC\+02:00", view.info()), view.info()
            t, ix = log.change(0)[:2]
            assert str(log.line_text(0)).split()[0] == app.store.time.text(t)
            assert app.store.time.text(t).startswith("19:2")

            app.store.time.mode = REL  # a reference on the frame of the register's first change
            row = next(r for r in range(len(app.store)) if app.store.frame(r).index == ix)
            app.store.time.toggle_reference(row, app.store.frame(row).t_ns, ix)
            app._after_time_change()
            await pilot.pause(0.3)
            assert app.store.time.mode == REF
            assert plot_text(view)[-1].rstrip().endswith(f"s from #{ix}")
            assert str(log.line_text(0)).split()[0] == "+0.000000"
    asyncio.run(go())
