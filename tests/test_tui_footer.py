"""The key bar: rebuilt when the keys it shows change, not at every focus change."""

import asyncio

from test_tui import SIZE, loaded, make_app

from sniffer.tui.footer import KeyBar


def bar_text(app) -> str:
    return " ".join(str(k.description) for k in app.query("FooterKey"))


def test_tab_switches_rebuild_the_key_bar_only_when_its_keys_change():
    async def go():
        app = make_app()
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            bar = app.query_one(KeyBar)
            await pilot.press("2", "1")
            await pilot.pause()
            first = bar.rebuilds
            assert first >= 1 and "Filter" in bar_text(app) and "Plot it" not in bar_text(app)
            for _ in range(5):  # Units and Frames show the same keys: no rebuild, though the focus moves
                await pilot.press("2", "1")
                await pilot.pause()
            assert app.focused is app.frame_list
            assert bar.rebuilds == first
            await pilot.press("3")  # the Registers tab adds its own key
            await pilot.pause()
            assert bar.rebuilds == first + 1 and "Plot it" in bar_text(app)
            await pilot.press("1")
            await pilot.pause()
            assert bar.rebuilds == first + 2 and "Plot it" not in bar_text(app)
    asyncio.run(go())
