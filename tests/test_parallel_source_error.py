"""A capture whose reading fails part way (here: bytes of a link the capture does not list, as the TUI's
multi-link export wrote them before its reads carried their link) gives with --jobs what one process
gives: the frames before the failure and the one error line, not an error from a later part's warm-up."""

from __future__ import annotations

import dataclasses

import pytest
from test_parallel import _cli
from test_tui_links import two_link_events

from sniffer.formats import FileSink


@pytest.fixture
def small_parts(monkeypatch):
    import sniffer.parallel.engine as engine

    monkeypatch.setattr(engine, "PART_EVENTS", 40)
    monkeypatch.setattr(engine, "WARM_EVENTS", 12)
    monkeypatch.setattr(engine, "OVER_EVENTS", 64)


def _write_raw(path, info, events) -> str:
    """The events as they are, straight to the MCAP writer (a capture session would refuse the unlisted link)."""
    out = FileSink("mcap", str(path), timed_flush=False)
    sink = out.open()
    sink.start(info)
    for e in events:
        sink.raw(e)
    sink.close()
    for o in out.outputs:
        o.commit()
    return str(path)


@pytest.mark.slow  # worker processes decode the parts
@pytest.mark.parametrize("command", ["replay", "diagnose"])
def test_a_source_error_mid_capture_is_the_same_with_jobs(capfd, tmp_path, small_parts, command):
    info, events = two_link_events()
    cut = len(events) // 3
    events = events[:cut] + [dataclasses.replace(e, link="") for e in events[cut:]]
    path = _write_raw(tmp_path / "unlisted-link.mcap", info, events)
    rc1, out1, err1 = _cli(capfd, command, path)
    rc2, out2, err2 = _cli(capfd, command, path, "--jobs", "2")
    assert "bytes of a link '' the capture does not list" in err1 and len(err1.strip().splitlines()) == 1
    assert (rc2, out2, err2) == (rc1, out1, err1)
    assert "warm-up" not in err2
