"""The public sigrok logic captures (.sr) decoded through sigrok-cli, as `sniffer replay FILE.sr --rx ...` does.

Truth: the byte CSVs beside them (sigrok's own UART decode, one run per
annotation class, merged: captures/refcaptures/sigrok/SOURCE.md) and sigrok's
modbus verdicts.  The frames from the raw samples must be exactly the byte
CSVs' frames: every time (integer ns from sample numbers), byte, role, pair and
annotation.  On the two-line capture the role comes from the channel.
"""

from __future__ import annotations

import pytest
from refdata import SIGROK, sigrok_crc_correct_frames, sigrok_line
from sigrok_tools import SR_NAMES, decode_source, need_sigrok_cli, ref_logic

from helpers import run_events
from sniffer.formats.bytecsv.reader import open_byte_csv
from sniffer.sources.files import FileSource


def _key(f):
    return (f.index, f.t_ns, f.t_end_ns, f.raw, f.protocol, f.role, f.crc_ok, f.pair, f.latency_ms, f.channel,
            f.idle_before_ns, [(a.code, a.start, a.end) for a in f.annotations], f.summary)


def _from_sr(name: str):
    need_sigrok_cli()
    src = FileSource(SIGROK / f"{name}.sr", logic=ref_logic(name))
    return decode_source(src, sigrok_line(name))


def test_the_six_captures_with_samples_are_here():
    assert SR_NAMES == ["brainchild-io-16do", "flowmeter_graph_tool", "flowmeter_target0_val0",
                        "flowmeter_target_0liter_per_min", "flowmeter_target_15liter_per_min",
                        "flowmeter_target_20liter_per_min"]


@pytest.mark.parametrize("name", SR_NAMES)
def test_frames_from_the_samples_are_the_byte_csvs_frames(name):
    info, events = open_byte_csv(str(SIGROK / f"{name}.bytes.csv"))
    expected = run_events(events, sigrok_line(name), info=info)
    frames = _from_sr(name)
    assert len(frames) == len(expected)
    assert [_key(f) for f in frames] == [_key(f) for f in expected]
    assert all(f.time_source == "byte" for f in frames)


@pytest.mark.parametrize("name", SR_NAMES)
def test_frames_from_the_samples_match_sigroks_modbus_verdicts(name):
    expected = sigrok_crc_correct_frames(name)
    ours, pos = {}, 0
    for f in _from_sr(name):
        if f.crc_ok:
            ours[(pos, pos + len(f.raw) - 1)] = f.role
        pos += len(f.raw)
    assert set(ours) == set(expected)
    assert all(role in expected[span] for span, role in ours.items())


def test_two_wire_capture_takes_roles_from_its_channels():
    """brainchild: channel 1 is what the slave receives (--rx: requests), channel 0 what it sends (--tx)."""
    frames = _from_sr("brainchild-io-16do")
    assert {f.channel for f in frames} == {"0", "1"}
    assert all(f.role == ("request" if f.channel == "1" else "response") for f in frames)
    assert all(f.pair is not None for f in frames)


def test_sample_times_are_exact_integer_ns():
    """4 MHz: a sample is 250 ns; every byte time is a whole number of samples, never a rounded float."""
    frames = _from_sr("flowmeter_graph_tool")
    assert frames[0].t_ns == 4_053_750  # sample 16215 (the byte CSV: 0.00405375 s)
    assert all(f.t_ns % 250 == 0 for f in frames)
