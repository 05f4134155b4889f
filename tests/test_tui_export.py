"""Export (x) and copy (y) from the TUI, under Pilot: files written by the project's sinks, read back with its
readers (MCAP reader and replay, pcap reader, CSV) and compared with the view they came from."""

import asyncio
import csv

import pytest
from tui_helpers import filled_sink, replay_frames

from sniffer.line import LineSettings
from sniffer.formats.pcap.format import LINKTYPE_USER0
from sniffer.capture.pipeline import Pipeline
from sniffer.formats.records import frame_record
from sniffer.formats.mcap.reader import read_frames
from sniffer.formats.pcap.reader import read_packets
from sniffer.sources.files import open_replay
from sniffer.tui.app import SnifferApp

from decoders.registry import default_registry

SIZE = (140, 45)


def make_app(tmp_path, name="errors.mcap") -> SnifferApp:
    _, _, registry = replay_frames(name)
    # the capture's path only places the default export file (next to it)
    return SnifferApp(filled_sink(name), None, source_label=name, capture_path=str(tmp_path / name),
                      registry=registry, clock=lambda: 0.0)


async def loaded(app, pilot):
    app.poll()
    await pilot.pause()
    assert app.caught_up


def notes(app) -> list[str]:
    return [str(n.message) for n in app._notifications]


async def export(app, pilot, *, fmt_moves: int = 0, what_moves: int = 0, path: str | None = None):
    """x, then the format / what radio sets moved right that many times, the path typed, Enter; waits for
    the worker.  Returns the modal's error line if it stayed open, else None."""
    assert app.screen is app.screen_stack[0]
    await pilot.press("x")
    screen = app.screen
    assert type(screen).__name__ == "ExportScreen"
    if what_moves:
        await pilot.press("shift+tab", "shift+tab", *["right"] * what_moves, "enter", "tab", "tab")
    if fmt_moves:
        await pilot.press("shift+tab", *["right"] * fmt_moves, "enter", "tab")
    if path is not None:
        screen.query_one("#export-path").value = path
    await pilot.press("enter")
    await app.workers.wait_for_complete()
    await pilot.pause()
    if app.screen is screen:
        return str(screen.query_one("#export-error").render())
    return None


def replayed(path):
    """Frames of a `sniffer replay` of the file (decoded again from its /raw)."""
    info, events = open_replay(str(path))
    out = []

    class Collect:
        def start(self, info): pass
        def raw(self, ev): pass
        def frame(self, f): out.append(f)
        def close(self): pass

    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1), default_registry(info.devices),
                 [Collect()], protocol=info.protocol)
    for ev in events:
        p.feed(ev)
    p.finish()
    return info, out


@pytest.mark.parametrize("fmt", ["mcap", "pcap", "csv"])
def test_export_the_filtered_view_and_read_it_back(tmp_path, fmt):
    async def go():
        app = make_app(tmp_path)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "u")  # this frame's unit only
            view = [app.store.frame(r) for r in app.store.view]
            assert 10 < len(view) < len(app.store) and len({f.unit for f in view}) == 1
            error = await export(app, pilot, fmt_moves=["mcap", "pcap", "csv"].index(fmt))
            assert error is None
            path = tmp_path / f"errors-view.{fmt}"
            assert f"{len(view)} frames -> {path}" in notes(app)[-1]
            assert app.export_status is None and not list(tmp_path.glob("*.part"))
            return app.sink.info, view, path

    info, view, path = asyncio.run(go())
    t0 = info.t0_ns
    if fmt == "mcap":
        assert read_frames(path) == [frame_record(f, t0) for f in view]  # the records as shown
        rinfo, again = replayed(path)  # and `sniffer replay` frames the same bytes again from its /raw
        assert (rinfo.baud, rinfo.parity, rinfo.protocol) == (info.baud, info.parity, info.protocol)
        assert [(f.raw, f.t_end_ns - rinfo.t0_ns) for f in again] == [(f.raw, f.t_end_ns - t0) for f in view]
        assert [f.summary for f in again] == [f.summary for f in view]
    elif fmt == "pcap":
        anchor = info.wall_anchor_ns
        assert read_packets(path) == [(LINKTYPE_USER0, anchor + f.t_ns - t0, f.raw) for f in view]
    else:
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert [(int(r["index"]), r["raw"], float(r["t"])) for r in rows] == \
            [(f.index, f.raw.hex(), (f.t_ns - t0) / 1e9) for f in view]
        with open(tmp_path / "errors-view.points.csv", newline="") as fh:
            points = list(csv.DictReader(fh))
        assert len(points) == sum(len(f.points) for f in view) > 0


def test_export_bookmarks_asks_before_replacing_and_reports_a_bad_path(tmp_path):
    async def go():
        app = make_app(tmp_path, "a510.mcap")
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            assert await export(app, pilot, what_moves=1) == "no bookmarks to export (m marks a frame)"
            await pilot.press("escape")
            await pilot.press("home", "down", "m", "down", "down", "m", "e")  # marks; then a filter they pass
            marked = [app.store.frame(r) for r in sorted(app.store.bookmarks)]
            target = tmp_path / "marks.pcap"
            target.write_bytes(b"old")
            error = await export(app, pilot, what_moves=1, fmt_moves=1, path=str(target))
            assert error == f"{target} exists: Enter again replaces it (or change the name)"
            assert target.read_bytes() == b"old"
            await pilot.press("enter")  # asked once: replaced
            await app.workers.wait_for_complete()
            await pilot.pause()
            assert notes(app)[-1] == f"2 frames -> {target}"
            assert [p[2] for p in read_packets(target)] == [f.raw for f in marked]
            # an unwritable place: one line in the modal, which stays open; nothing is written
            nowhere = tmp_path / "no-such-folder"
            error = await export(app, pilot, path=str(nowhere / "x.mcap"))
            assert error == f"{nowhere / 'x.mcap'}: folder {nowhere} does not exist"
            await pilot.press("escape")
            for path in ("/proc/no-export-here.pcap", "/proc/no-export-here.mcap"):  # no file can be made there
                error = await export(app, pilot, path=path)
                assert error.startswith(f"{path}: ") and "cannot" in error and "\n" not in error
                await pilot.press("escape")
            error = await export(app, pilot, path=str(tmp_path / "a510.mcap"))  # the capture itself
            assert error == f"{tmp_path / 'a510.mcap'}: is also an input of this command; write to another file"
            assert not list(tmp_path.glob("*.part"))
    asyncio.run(go())


def test_the_default_export_name_never_replaces_a_file(tmp_path):
    from sniffer.tui.export import default_path

    cap = str(tmp_path / "line3.mcap")
    assert default_path(cap, "view", "mcap") == str(tmp_path / "line3-view.mcap")
    (tmp_path / "line3-view.mcap").write_bytes(b"")
    assert default_path(cap, "view", "mcap") == str(tmp_path / "line3-view-2.mcap")
    (tmp_path / "line3-bookmarks.points.csv").write_bytes(b"")  # CSV writes two files: either one counts
    assert default_path(cap + ".part", "bookmarks", "csv") == str(tmp_path / "line3-bookmarks-2.csv")
    assert default_path(None, "view", "pcap", folder=str(tmp_path)) == str(tmp_path / "capture-view.pcap")


def test_y_copies_the_selected_frames_hex(tmp_path):
    async def go():
        app = make_app(tmp_path)
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            await pilot.press("home", "down", "down", "y")
            f = app.selected_frame
            assert app.clipboard == f.raw.hex() and len(f.raw) > 4
            assert notes(app)[-1].startswith(f"copied frame #{f.index}: {len(f.raw)} bytes, {f.raw[:4].hex(' ')}")
    asyncio.run(go())


def test_help_and_docs_name_the_keys_of_export_copy_and_the_byte_view():
    from pathlib import Path

    from sniffer.tui.app import HELP, SnifferApp

    keys = {b.key for b in SnifferApp.BINDINGS}
    page = (Path(__file__).resolve().parent.parent / "docs" / "tui.md").read_text()
    for key, words in (("x", "export"), ("y", "copy"), ("6", "bytes")):
        assert key in keys
        assert f"[b]{key}[/b]" in HELP and words in HELP.split(f"[b]{key}[/b]")[1][:40].lower()
        assert f"`{key}`" in page


def test_export_of_a_finished_replay_writes_every_frame_beside_the_capture(tmp_path, monkeypatch):
    """`replay --tui` as the command builds it (sniffer.tui.run.session_app): the replay has ended, so its session's
    stop event is set, before `x`; an export of more frames than the writer does between two looks at its stop
    (2,048) is written whole, proposed beside the capture (not in the working folder), and says so."""
    from sniffer.events import CaptureInfo
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.simulator import get_scenario, simulate, wire_chunks
    from sniffer.formats.mcap.sink import McapSink
    from sniffer.sources.files import FileSource
    from sniffer.tui.run import session_app
    from sniffer.tui.sink import TuiSink

    sc = get_scenario("stress")
    cap = tmp_path / "captures" / "stress.mcap"  # 8 s of it: about 3,000 frames
    cap.parent.mkdir()
    info = CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits, protocol=sc.protocol)
    Session(CaptureSpec(), EventSource(info, wire_chunks(simulate(sc, sc.line, 8.0, 1))), [McapSink(cap)]).run()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)

    async def go():
        sink = TuiSink()
        session = Session(CaptureSpec(), FileSource(str(cap)), [sink])
        session.open()
        app = session_app(session, sink, source_label=str(cap), source_path=str(cap), clock=lambda: 0.0)
        async with app.run_test(size=SIZE) as pilot:
            while not app.caught_up:
                await pilot.pause(0.05)
            await loaded(app, pilot)
            assert session.stop.is_set() and len(app.store.view) > 2048  # the replay is over
            assert await export(app, pilot) is None
            path = cap.parent / "stress-view.mcap"
            assert notes(app)[-1] == f"{len(app.store.view)} frames -> {path}"
            return path, [frame_record(app.store.frame(r), app.sink.info.t0_ns) for r in app.store.view]

    path, shown = asyncio.run(go())
    assert read_frames(path) == shown
    assert not list(elsewhere.iterdir()) and not list(cap.parent.glob("*.part"))


def test_the_default_export_of_a_rotated_capture_goes_beside_its_folder(tmp_path):
    from sniffer.tui.export import default_path

    folder = tmp_path / "cab3"
    folder.mkdir()
    want = str(tmp_path / "cab3-view.mcap")  # not inside: `replay FOLDER` reads what is in it
    for named in (str(folder), str(folder) + "/", str(folder / "index.json")):
        assert default_path(named, "view", "mcap") == want
