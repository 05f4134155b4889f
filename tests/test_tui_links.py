"""The TUI over a capture of two links at their own speeds (Pilot, fixed size): a link column, the `link:`
filter, units and registers per link (unit 1 on link a is not unit 1 on link b), the frames in time order, every
link's settings in the status bar, and each link's gaps in its own character times in the byte view."""

from __future__ import annotations

import asyncio
import functools
import re

from tui_helpers import frames_from_reads, registry_shadow, screen_text

from sniffer.events import CaptureInfo, Chunk
from sniffer.frame import LinkUnit
from sniffer.line import LineSettings
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.simulator.bus import simulate
from sniffer.simulator.chunks import wire_chunks
from sniffer.simulator.scenario import get_scenario
from sniffer.tui.app import SnifferApp
from sniffer.tui.store import FrameStore
from sniffer.tui.sink import TuiSink

SIZE = (140, 45)
LINES = {"a": LineSettings(19200, "E", 1), "bb": LineSettings(38400, "N", 1)}
LINKS = tuple(LINES)
ROW = re.compile(r"^..\s*\d+\.\d{6} ")  # a row of the frame list (its time column)


def two_link_events() -> tuple[CaptureInfo, list[Chunk]]:
    """Two simulated lines of the default scenario (the same units, other values, other speeds), their bytes
    merged by time: the info and events of one capture of two links."""
    events = []
    for seed, (name, line) in enumerate(LINES.items()):
        events += [Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", name)
                   for c in wire_chunks(simulate(get_scenario("default"), line, 3.0, seed=seed + 1))]
    events.sort(key=lambda c: c.t_ns)
    info = CaptureInfo(links=[{"name": n, "ports": [], "tap": False, "baud": line.baud, "parity": line.parity,
                               "stopbits": line.stopbits} for n, line in LINES.items()])
    return info, events


@functools.cache
def _two_links():
    """(info, frames, {link: registry}): two_link_events decoded as one capture of two links."""
    info, events = two_link_events()
    sink = TuiSink()
    session = Session(CaptureSpec(), EventSource(info, events), [sink])
    session.run()
    return session.info, sink.drain(), session.pipeline.registries, sink.drain_reads()


def _app() -> SnifferApp:
    info, frames, registries, _ = _two_links()
    sink = TuiSink()
    sink.start(info)
    sink.frames(frames)
    sink.close()
    return SnifferApp(sink, None, source_label="two links", registry=registries["a"], clock=lambda: 0.0)


async def _loaded(app, pilot):
    app.poll()
    await pilot.pause()
    assert app.caught_up


def test_reads_are_marked_with_the_frames_of_their_own_link():
    """The byte view's reads: every link is a stream of its own; reads keep the order they came in."""
    from sniffer.formats.records import frame_json, loads
    from sniffer.processes.stream import parse_reads, read_item, reads_line

    info, frames, _, reads = _two_links()
    assert {r.link for r in reads} == set(LINKS)
    assert [r.offset for r in reads] == sorted(r.offset for r in reads)  # in the order read, every link's bytes
    assert frames_from_reads(reads) == {f.index: f.raw for f in frames}
    assert all({next(f.link for f in frames if f.index == i) for i in r.frames} == {r.link} for r in reads)
    # a viewer gets them over the socket as they are
    line = loads(reads_line([read_item(r, info.t0_ns) for r in reads]).decode())
    assert parse_reads(line, info.t0_ns) == reads
    assert loads(frame_json(frames[0], info.t0_ns))["link"] == frames[0].link


def test_store_keeps_units_and_registers_per_link():
    info, frames, registries, _ = _two_links()
    store = FrameStore(info.t0_ns)
    store.add(frames)
    units = {f.unit for f in frames if f.unit is not None}
    assert set(store.units) == {LinkUnit(n, u) for n in LINKS for u in units}
    want = {(LinkUnit(n, u), t, a): v for n in LINKS for (u, t, a), v in registry_shadow(registries[n]).items()}
    assert {k: rv.raw for k, rv in store.registers.items()} == want  # each link's decoders' own shadow
    # the same register of unit 1 on the two links holds each link's value, not one glued value
    both = [k for k in want if k[0].link == "a" and (LinkUnit("bb", 1), k[1], k[2]) in want and k[0].unit == 1]
    assert both and any(want[k] != want[(LinkUnit("bb", 1), k[1], k[2])] for k in both)


def test_link_column_filter_and_units_per_link():
    async def go():
        app = _app()
        async with app.run_test(size=SIZE) as pilot:
            await _loaded(app, pilot)
            store = app.store
            assert store.several_links and app.frame_list.layout_columns().has("link")
            lines = screen_text(app).splitlines()
            col = next(line.index(" link ") + 1 for line in lines if " link " in line)  # the column's cells
            assert {line[col:col + 3] for line in lines if ROW.match(line)} == {"a  ", "bb "}
            await pilot.press("slash", *"link:bb", "enter")
            assert store.filter.links == {"bb"}
            assert store.view and all(store.frames[r].link == "bb" for r in store.view)
            await pilot.press("c", "home", "down")  # a frame of unit u on some link
            f = app.selected_frame
            await pilot.press("u")  # that unit, of that link only
            assert store.filter.units == {f.unit} and store.filter.links == {f.link}
            assert all((store.frames[r].link, store.frames[r].unit) == (f.link, f.unit) for r in store.view)
            await pilot.press("u", "2")
            await pilot.pause()
            table = app.query_one("#unitstable")
            assert table.row_count == len(store.units) == 2 * len({u.unit for u in store.units})
            assert str(table.get_row("bb:1")[0]) == "bb:1"
            await pilot.press("3")
            await pilot.pause()
            regs = app.query_one("#regs")
            assert regs.row_count == len(store.registers)
            assert {str(regs.get_row(f"{k[0]}:{k[1]}:{k[2]}")[0]) for k in store.registers} == \
                {str(k[0]) for k in store.registers}
    asyncio.run(go())


def test_one_link_shows_no_link_column():
    from tui_helpers import store_of

    store = store_of("errors.mcap")
    assert not store.several_links and store.link_names == [""]


def test_frames_of_both_links_are_listed_in_time_order():
    """Δt is never negative: the list holds the frames of both links in time order, numbered in that order."""
    async def go():
        app = _app()
        async with app.run_test(size=SIZE) as pilot:
            await _loaded(app, pilot)
            frames = [app.store.frame(r) for r in app.store.view]
            assert {f.link for f in frames} == set(LINKS)
            assert [f.t_ns for f in frames] == sorted(f.t_ns for f in frames)
            assert [f.index for f in frames] == list(range(len(frames)))
            for keys in (("home",), ("end",)):
                await pilot.press(*keys)
                lines = screen_text(app).splitlines()
                col = next(line.index("Δt") for line in lines if "Δt" in line)
                cells = [line[col - 7:col + 2].strip() for line in lines if ROW.match(line)]
                assert len(cells) > 20 and all(c.endswith("ms") for c in cells[1:])
                assert not any(c.startswith("-") for c in cells)
    asyncio.run(go())


def test_the_status_bar_shows_every_links_settings():
    from sniffer.tui.status import status_text

    async def go():
        app = _app()
        async with app.run_test(size=SIZE) as pilot:
            await _loaded(app, pilot)
            text = status_text(app, width=400).plain
            assert "a 19200 8E1, bb 38400 8N1 modbus-rtu" in text
    asyncio.run(go())


def test_the_byte_view_counts_each_links_gaps_in_that_links_characters():
    """The chars column is the gap in character times of the read's own link: gap (ms) / its character time."""
    async def go():
        app = _app()
        info, _, _, reads = _two_links()
        app.sink.reads(reads)
        async with app.run_test(size=SIZE) as pilot:
            await _loaded(app, pilot)
            await pilot.press("6")
            bv, seen = app.byte_view, set()
            for seq in range(app.reads.first_seq, app.reads.end_seq):
                text = bv.format_line(seq, 0, bv._layout[1]).plain
                gap, chars = text[17:27].strip(), text[27:35].strip()
                if not chars.endswith("ch"):
                    continue
                link = app.reads.get(seq).link
                char_ms = LINES[link].char_ns / 1e6
                assert abs(float(chars[:-2]) * char_ms - float(gap[:-2])) <= 0.05 * char_ms + 0.001, text
                seen.add(link)
            assert seen == set(LINKS)
    asyncio.run(go())
