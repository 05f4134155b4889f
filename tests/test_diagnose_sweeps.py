"""Seeded sweeps of `sniffer diagnose` over plants it was not written against (tests/plants.py): baud 9600-115200,
8N1/8E1/8O1/8N2, addresses 1-247, every model mixed, poll cycles 50 ms-2 s; each cause at a severity drawn
between the limit docs/diagnose.md states and gross, intermittent, and two at once; healthy lines, busy ones
too, with nothing above info.  Each prints its figures (found, false alarms) for the benchmarks' notes."""

from __future__ import annotations

import dataclasses

import pytest

from plants import CAUSES, cause, diagnose, no_trips, plant, verdict, with_fault

SEEDS = range(6)
HEALTHY = range(30)
# a cause's noise read as a second master is the masters rework's to settle (it models who is talking): counted
# and printed here, not failed on
ELSEWHERE = frozenset({"second_master"})


def _false(p, findings) -> list:
    _, false = verdict(p, findings)
    return false


@pytest.mark.parametrize("kind", sorted(CAUSES))
def test_each_cause_is_found_on_its_unit_above_its_limit(kind):
    missed, alarms, elsewhere = [], [], []
    for seed in SEEDS:
        p = cause(kind, seed)
        findings, _ = diagnose(p)
        found, false = verdict(p, findings)
        if not found:
            missed.append(p.name)
        alarms += [(p.name, f) for f in false if f[0] not in ELSEWHERE]
        elsewhere += [(p.name, f) for f in false if f[0] in ELSEWHERE]
    print(f"{kind}: found {len(SEEDS) - len(missed)} of {len(SEEDS)}, false alarms {len(alarms)}, "
          f"second master on a noisy line {len(elsewhere)}")
    assert not missed, missed
    assert not alarms, alarms


def test_each_cause_at_its_documented_limit():
    """The weakest case docs/diagnose.md names, on a plain plant (19200 8E1, two units, 100 ms)."""
    base = plant(3, models=("a510", "generic"), cycle_ms=100.0)
    base = dataclasses.replace(base, scenario=no_trips(base.scenario))
    for kind, (_, limit) in CAUSES.items():
        if limit is None:
            continue
        p = cause(kind, 1, severity=limit, base=base)
        findings, _ = diagnose(p)
        found, false = verdict(p, findings)
        assert found, (p.name, [(f.kind, f.unit) for f in findings if f.severity != "info"])
        assert not [f for f in false if f[0] not in ELSEWHERE], (p.name, false)


def test_healthy_plants_give_nothing_above_info():
    bad = []
    for seed in HEALTHY:
        p = plant(seed)
        p = dataclasses.replace(p, scenario=no_trips(p.scenario))
        findings, _ = diagnose(p)
        bad += [(p.name, f) for f in _false(p, findings)]
    print(f"healthy plants: {len(HEALTHY)}, false alarms {len(bad)}")
    assert not bad, bad


def test_busy_healthy_lines_give_nothing_above_info():
    """Polled back to back (90 % busy and more), drives started and stopped every minute, a probe the drives
    refuse at start and a unit busy now and then."""
    bad, shares = [], []
    for seed in range(8):
        p = plant(100 + seed, busy=True)
        sc = dataclasses.replace(no_trips(p.scenario), setpoint_change_s=60.0, setpoint_range_hz=(0.0, 50.0))
        p = dataclasses.replace(p, scenario=sc, seconds=60.0)
        findings, _ = diagnose(p)
        bad += [(p.name, f) for f in _false(p, findings)]
        shares += [f.evidence["line_busy_share"] for f in findings if f.kind == "poll_cycle"]
    print(f"busy plants: 8, line busy {min(shares):.0%}-{max(shares):.0%}, false alarms {len(bad)}")
    assert min(shares) >= 0.6 and max(shares) >= 0.9
    assert not bad, bad


@pytest.mark.parametrize("first,second", [
    ("bus_unbiased", "unit_silent"), ("noise_during_ramps", "unit_silent"), ("driver_disable_early", "unit_silent"),
    # one cause's damage over the other's signs: the cut's damage is set apart from the load test (correlate.py);
    # a drive whose answers are nearly all cut still trips in the master's fault resets (drives.py); strays glued
    # after intact answers are the floating line's, not a cut last byte (wiring.py)
    ("noise_correlated_with_load", "driver_enable_late"), ("driver_enable_late", "drive_fault"),
    ("latency_drift", "bus_unbiased"), ("driver_disable_early", "drive_fault"), ("bus_unbiased", "driver_enable_late"),
    # a known miss (strict: it fails loudly once fixed)
    pytest.param("driver_disable_early", "noise_correlated_with_load", marks=pytest.mark.xfail(
        strict=True, reason="a USB adapter's reads break each cut answer into several noise bursts, which no driver "
                            "finding claims: the cut's damage, counted several times, hides the load's")),
])
def test_two_causes_at_once_are_both_found(first, second):
    for seed in range(3):
        p = cause(first, seed)
        q = cause(second, seed + 50, base=dataclasses.replace(p, faults=(), expect=()))
        both = dataclasses.replace(q, faults=p.faults + q.faults, expect=p.expect + q.expect,
                                   seconds=max(p.seconds, q.seconds))
        findings, _ = diagnose(both)
        found, false = verdict(both, findings)
        assert found, (both.name, [(f.kind, f.unit) for f in findings if f.severity != "info"])
        assert not [f for f in false if f[0] not in ELSEWHERE], (both.name, false)


def test_a_silence_that_comes_twice_on_any_plant_is_two_episodes():
    for seed in range(4):
        p = cause("unit_silent", seed)
        unit = p.expect[0][1]
        span = max(10.0, 12 * p.cycle_s())
        twice = with_fault(dataclasses.replace(p, faults=(), expect=()),
                           f"unit_silent:{unit}@{span:g}-{2 * span:g}", (("unit_silent", unit),), 6 * span)
        twice = with_fault(twice, f"unit_silent:{unit}@{4 * span:g}-{5 * span:g}", ())
        findings, _ = diagnose(twice)
        (f,) = [x for x in findings if x.kind == "unit_silent" and x.unit == unit]
        assert f.episode_count == 2, (twice.name, f.when())


def test_a_drive_whose_answers_are_all_cut_still_trips_in_the_masters_resets():
    """Every answer cut (its fault register unreadable): the master's fault resets say the drive trips; the same
    cut on a drive that never trips says no such thing."""
    for seed in range(2):
        p = cause("drive_fault", seed)
        unit = p.expect[0][1]
        cut = with_fault(p, f"driver_enable_late:{unit},1", (("driver_enable_late", unit),))
        findings, _ = diagnose(cut)
        trips = [f for f in findings if f.kind == "drive_fault" and f.unit == unit]
        assert trips and trips[0].severity == "error", (cut.name, [(f.kind, f.unit) for f in findings])
        f = trips[0]
        if "fault_resets_written" in f.evidence:  # (a cut that leaves the rest intact may let the fault be read)
            assert f.evidence["fault_resets_written"] >= 2 and f.evidence["answers_lost_share"] >= 0.5
            assert "fault reset" in f.text and "None" not in f.text and "{" not in f.text, f.text
        calm = dataclasses.replace(cut, scenario=no_trips(cut.scenario), faults=cut.faults[1:])
        findings, _ = diagnose(calm)
        assert not [f for f in findings if f.kind == "drive_fault"], calm.name


def test_a_latency_drift_that_comes_and_goes_is_found_in_its_span():
    """latency_drift@FROM-TO: the unit's turnaround grows from FROM and is back to what it was at TO; found on its
    unit with an episode inside the span, and nothing else above info."""
    for seed in range(4):
        p = cause("latency_drift", seed, severity=10.0)
        unit = p.expect[0][1]
        span = max(30.0, 110 * p.cycle_s())  # (a median per stretch of 1/64 of the capture needs 5 answers)
        q = with_fault(dataclasses.replace(p, faults=(), expect=()), f"latency_drift:{unit}@{span:g}-{2 * span:g},10",
                       (("latency_drift", unit),), 3 * span)
        findings, _ = diagnose(q)
        found, false = verdict(q, findings)
        assert found and not false, (q.name, [(f.kind, f.unit) for f in findings if f.severity != "info"])
        (f,) = [x for x in findings if x.kind == "latency_drift"]
        assert any(e.from_s < 2 * span and e.to_s > span for e in f.episodes), (q.name, f.when())
