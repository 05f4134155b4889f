"""The MCAP the TUI exports from a view of several links (Pilot) replays, diagnoses and reports as the
capture it came from: every /raw read carries its link, so a replay hands each link's bytes to that link's
own framer again (also decoded by parts, --jobs)."""

from __future__ import annotations

import asyncio

import orjson
from test_tui_export import export, loaded, notes
from test_tui_links import SIZE, _app, two_link_events

from sniffer import cli
from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.formats import FileSink


def _original(tmp_path):
    """The two-link capture as `sniffer live P1 P2 --out` writes it (per-byte times, each read's link)."""
    info, events = two_link_events()
    path = tmp_path / "two-links.mcap"
    Session(CaptureSpec(), EventSource(info, events), [FileSink("mcap", str(path), timed_flush=False)]).run()
    return path


def _exported(tmp_path):
    async def go():
        app = _app()
        app.capture_path = str(tmp_path / "two-links.mcap")
        async with app.run_test(size=SIZE) as pilot:
            await loaded(app, pilot)
            assert app.store.several_links
            n = len(app.store.view)
            error = await export(app, pilot, path=str(tmp_path / "two-links-view.mcap"))
            assert error is None and f"{n} frames -> " in notes(app)[-1]
            return n

    n = asyncio.run(go())
    return tmp_path / "two-links-view.mcap", n


def _out(capsys, *argv) -> tuple[int, str]:
    rc = cli.main(list(argv))
    cap = capsys.readouterr()
    assert "error" not in cap.err, cap.err
    return rc, cap.out


def _frames(capsys, path, *more) -> dict[str, list]:
    """Each link's frames in order (across links, frames that start together may come in either order: an
    export's start times are estimated from each frame's end and its link's baud)."""
    rc, out = _out(capsys, "replay", str(path), "--format", "jsonl", *more)
    assert rc == 0
    links: dict[str, list] = {}
    for r in map(orjson.loads, out.splitlines()):
        links.setdefault(r["link"], []).append((r["unit"], r["function"], r["role"], r["crc_ok"], r["raw"],
                                                r["summary"]))
    return links


def test_multi_link_export_replays_diagnoses_and_reports_as_its_capture(tmp_path, capsys):
    original = _original(tmp_path)
    path, n = _exported(tmp_path)
    want = _frames(capsys, original)
    assert sum(map(len, want.values())) == n and set(want) == {"a", "bb"}
    assert _frames(capsys, path) == want
    assert _frames(capsys, path, "--jobs", "2") == want  # decoded by parts: no warm-up error either

    def findings(p, *more):
        rc, out = _out(capsys, "diagnose", str(p), "--format", "json", *more)
        assert rc in (0, 1)
        return sorted((f["kind"], f["severity"], f.get("link"), f.get("unit")) for f in orjson.loads(out)["findings"])

    assert findings(path) == findings(original) == findings(path, "--jobs", "2")
    assert {f[2] for f in findings(path)} == {"a", "bb"}
    report = tmp_path / "report.html"
    rc, _ = _out(capsys, "report", str(path), "--out", str(report))
    assert rc == 0 and report.stat().st_size > 0
