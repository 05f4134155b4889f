"""`simulate --fault KIND[:UNIT][@FROM-TO][,SEVERITY]`: the syntax, and each part doing on the simulated wire what
it says (ground truth from the simulator's own frames: who sent what, when, which fault it carries)."""

from __future__ import annotations

import math

import pytest

from sniffer.simulator import FAULT_CRC, FAULT_NOISE, KIND_NOISE, simulate
from sniffer.simulator.faults import FaultError, apply, parse, parse_faults
from sniffer.simulator.sources import scenario_named


def test_the_syntax_reads_unit_span_and_severity():
    (f,) = parse_faults(["unit_silent:5@20-60,0.9"])
    assert (f.kind, f.unit, f.start_s, f.end_s, f.severity) == ("unit_silent", 5, 20.0, 60.0, 0.9)
    (g,) = parse_faults(["bus_unbiased,mild"])
    assert g.severity == 0.007 and g.end_s == math.inf and not g.spanned
    assert parse(["driver_enable_late:2", "bus_unbiased"]) == (("driver_enable_late", 2), ("bus_unbiased", None))
    assert f.label() == "unit_silent:5@20-60,0.9"


@pytest.mark.parametrize("bad", ["drive_fault:1@3-4", "bus_unbiased,7", "unit_silent:5@30-20", "unit_silent:5@x",
                                 "eeprom_wear:1,0.5", "bus_unbiased,lots", "nonsense"])
def test_a_bad_fault_is_one_clear_error(bad):
    with pytest.raises(FaultError, match="--fault"):
        parse_faults([bad])


def _frames(faults, seconds=40.0, scenario="default", seed=3):
    sc = apply(scenario_named(scenario), faults)
    return list(simulate(sc, sc.line, seconds, seed))


def test_a_unit_silent_in_a_span_answers_before_and_after():
    frames = _frames(["unit_silent:5@10-25"])
    answers = [f.t_ns / 1e9 for f in frames if f.role in ("response", "exception") and f.unit == 5]
    assert not [t for t in answers if 10.05 < t < 25.0]
    assert any(t < 10 for t in answers) and any(t > 25 for t in answers)


def test_sparse_strays_come_at_the_severity_asked():
    frames = _frames(["bus_unbiased,0.007"], seconds=60.0)
    strays = sum(1 for f in frames if f.kind == KIND_NOISE and f.fault == FAULT_NOISE)
    rate = strays / (len(frames) - strays)
    assert 0.003 < rate < 0.015


def test_noise_during_ramps_hits_frames_only_while_the_drive_accelerates():
    sc = apply(scenario_named("default"), ["noise_during_ramps:1,gross"])
    hit = [f for f in simulate(sc, sc.line, 40.0, 3) if f.fault == FAULT_CRC]
    clean = [f for f in _frames([]) if f.fault == FAULT_CRC]
    assert len(hit) >= 10 and not clean
    # the hits cluster in time (the ramps), not spread over the capture: most 1 s windows have none
    windows = {int(f.t_ns / 1e9) for f in hit}
    assert len(windows) < 0.6 * 40


def test_two_causes_at_once_and_a_fault_that_comes_twice():
    frames = _frames(["bus_unbiased", "unit_silent:2@5-10", "unit_silent:2@20-25"])
    assert any(f.kind == KIND_NOISE for f in frames)
    answers = [f.t_ns / 1e9 for f in frames if f.role in ("response", "exception") and f.unit == 2]
    assert not [t for t in answers if 5.05 < t < 10 or 20.05 < t < 25]
    assert [t for t in answers if 11 < t < 19] and [t for t in answers if t > 26]
