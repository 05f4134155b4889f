"""Snapshot tests of the main views (pytest-textual-snapshot), 140x45 and 80x24, deterministic replay.

Update after a reviewed change: `.venv/bin/pytest tests/test_tui_snapshots.py --snapshot-update`.
"""

import pytest

pytest.importorskip("pytest_textual_snapshot")

from tui_helpers import filled_sink, replay_frames

from sniffer.tui.app import SnifferApp

SIZE = (140, 45)


def make_app(name):
    _, _, registry = replay_frames(name)
    return SnifferApp(filled_sink(name), None, source_label=name, registry=registry, clock=lambda: 0.0)


async def _load(pilot):
    pilot.app.poll()
    await pilot.pause()


def test_frames_errors(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("home", "n", "n", "n", "n")  # an exception response

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)


def test_frames_errors_only_detail(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("e", "home", "down", "enter", "down", "down", "down")

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)


def test_units(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("2")

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)


def test_registers(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("3", "down", "down")

    assert snap_compare(make_app("a510.mcap"), terminal_size=SIZE, run_before=before)


def test_transactions(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("4", "home", "n", "n", "n")  # a timeout, then an exception, with the unit's histogram

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)


def test_bytes(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("home", *["down"] * 6, "6")  # a request the USB adapter split across two reads

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)


def test_frames_80x24(snap_compare):
    """Issue 11: at 80x24 the summary fell off screen; the columns fit (the model gives way), Δt shows."""
    async def before(pilot):
        await _load(pilot)
        await pilot.press("home", "n", "n", "n", "n")

    assert snap_compare(make_app("errors.mcap"), terminal_size=(80, 24), run_before=before)


def test_units_80x24(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("2")

    assert snap_compare(make_app("errors.mcap"), terminal_size=(80, 24), run_before=before)


def test_transactions_80x24(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("4", "home", "n")

    assert snap_compare(make_app("errors.mcap"), terminal_size=(80, 24), run_before=before)


def test_plot(snap_compare):
    """Two registers of two units on the plot (Hz left, A right), zoomed twice around a cursor."""
    async def before(pilot):
        await _load(pilot)
        await pilot.press("3", *["down"] * 6, "a", *["down"] * 21, "a", "5", "full_stop", *["comma"] * 20,
                          "plus", "plus")

    assert snap_compare(make_app("a510.mcap"), terminal_size=SIZE, run_before=before)


def test_verdicts(snap_compare):
    async def before(pilot):
        await _load(pilot)
        await pilot.press("7", "down")  # the second finding highlighted: its evidence below

    assert snap_compare(make_app("errors.mcap"), terminal_size=SIZE, run_before=before)
