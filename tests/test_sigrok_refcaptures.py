"""The six sigrok captures replay to exactly the frames sigrok marks "CRC correct".

Truth: sigrok's modbus decoder verdicts in captures/refcaptures/sigrok
(public domain captures from sigrok-dumps).  On the single-line flowmeter
captures sigrok parses every frame both ways; our role must be one of the
directions whose parse it found CRC-correct.
"""

from __future__ import annotations

import pytest
from refdata import SIGROK, SIGROK_NAMES, sigrok_crc_correct_frames, sigrok_line

from helpers import run_events
from sniffer.formats.bytecsv.reader import open_byte_csv


def _our_frames(name: str):
    info, events = open_byte_csv(str(SIGROK / f"{name}.bytes.csv"))
    return run_events(events, sigrok_line(name), info=info)


def test_all_six_captures_present():
    assert len(SIGROK_NAMES) == 7  # 6 upstream captures, flowmeter in 5 files
    assert {n.split("_")[0] for n in SIGROK_NAMES} == {"brainchild-io-16do", "flowmeter", "wizmodbus"}


@pytest.mark.parametrize("name", SIGROK_NAMES)
def test_crc_correct_frames_match_sigrok(name):
    expected = sigrok_crc_correct_frames(name)
    frames = _our_frames(name)
    ours: dict[tuple[int, int], str] = {}
    pos = 0
    for f in frames:
        if f.crc_ok:
            ours[(pos, pos + len(f.raw) - 1)] = f.role
        pos += len(f.raw)
    assert set(ours) == set(expected), f"{name}: frame spans differ from sigrok's CRC-correct ADUs"
    for span, role in ours.items():
        assert role in expected[span], f"{name}: frame at bytes {span} is a {role}, sigrok: {expected[span]}"
    assert not any(f.is_noise for f in frames)
    assert not any(f.crc_ok is False for f in frames)


@pytest.mark.parametrize("name", SIGROK_NAMES)
def test_every_request_is_answered_and_paired(name):
    frames = _our_frames(name)
    by_index = {f.index: f for f in frames}
    for f in frames:
        assert f.role in ("request", "response")
        assert f.pair is not None, f"{name}: frame #{f.index} {f.raw.hex()} unpaired"
        peer = by_index[f.pair]
        assert peer.pair == f.index and peer.role != f.role
        if f.role == "response":
            assert 0 < f.latency_ms < 50
            assert not [a for a in f.annotations if a.severity != "info"]


def test_turnaround_below_t35_is_reported_not_glued():
    """wizmodbus slaves answer after 2.6-3.1 characters: each such response is its own frame."""
    frames = _our_frames("wizmodbus")
    short = [f for f in frames if any(a.code == "modbus.timing.t35" for a in f.annotations)]
    assert len(short) == 44
    assert all(f.role == "response" for f in short)


def test_read_response_takes_addresses_from_its_request():
    frames = _our_frames("wizmodbus")
    req, rsp = frames[0], frames[1]
    assert req.raw.hex() == "010303e80002447b"
    assert [p["address"] for p in rsp.points] == [0x3E8, 0x3E9]
    assert [p["raw"] for p in rsp.points] == [0x5266, 0x5707]
