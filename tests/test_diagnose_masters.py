"""A second master in every form, and healthy lines, over seeded plants (tests/sweeps.py): baud 9600-115200,
8N1/8E1/8O1/8N2, unit addresses 1-247, unit mixes, poll cycles 50 ms-2 s.  Each form is found on the unit it
polls in most plants (the measured rate is held, not a hand-picked seed), and no healthy plant gets a finding
above info."""

from __future__ import annotations

import pytest

from sniffer.simulator.faults import SECOND_MASTERS, apply, parse
from sniffer.simulator.bus import simulate

from sweeps import alarms, busy, diagnose_plant, draw, scenario, tally

SEEDS = range(1, 9)
FOUND_AT_LEAST = 0.6  # the share of plants each form is found in (measured: see docs/diagnose.md)


@pytest.mark.parametrize("kind", sorted(SECOND_MASTERS))
def test_each_second_master_form_is_found_on_the_unit_it_polls(kind):
    results = []
    for seed in SEEDS:
        plant = draw(seed)
        results.append((plant.label(), ("second_master", plant.units[1]),
                        diagnose_plant(plant, [f"{kind}:{{u1}}"], seconds=60)))
    t = tally(results)
    assert t["found"] >= FOUND_AT_LEAST * t["runs"], t["missed_runs"]
    # where the second master is missed, the damage its collisions leave is still said (line_damage): true, not
    # a false alarm; where it is found, that finding explains the damage and nothing else may be raised
    missed = {label for label, _ in t["missed_runs"]}
    wrong = [r for r in t["false_runs"]
             if any(k != "second_master" and not (k == "line_damage" and r[0] in missed) for k, _ in r[1])]
    assert not wrong, wrong


def test_healthy_plants_give_nothing_above_info():
    t = tally([(draw(s).label(), None, diagnose_plant(draw(s), (), seconds=60)) for s in SEEDS])
    assert t["false_alarms"] == 0, t["false_runs"]


def test_a_second_master_on_a_quiet_line_keeps_its_own_clock_and_never_collides():
    plant = draw(3)
    sc = apply(scenario(plant), [f"second_master_polite:{plant.units[1]}"])
    frames = sorted(simulate(sc, sc.line, 20, 3), key=lambda f: f.t_ns)
    assert all(a.t_end_ns <= b.t_ns for a, b in zip(frames, frames[1:])), "the polite one waits for a quiet line"
    blind = apply(scenario(plant), [f"second_master_blind:{plant.units[1]}"])
    assert any(f.kind == "corrupted" or f.fault for f in simulate(blind, blind.line, 20, 3)), "the blind one collides"


def test_the_finding_says_in_words_what_the_second_master_reads_and_how_often():
    plant = draw(3)
    (f,) = [x for x in diagnose_plant(plant, [f"second_master_fc04:{plant.units[1]}"], 60)
            if x.kind == "second_master"]
    assert f.unit == plant.units[1]
    assert "about every" in f.text and "fc04" in f.text, f.text
    assert "None" not in f.text and "{" not in f.text
    # each request type labelled with the master it most likely comes from: the fc04 reads the second's, the
    # first master's cycle its own; in words, a table (the rest in --format json)
    by = f.evidence["requests_by_master"]
    second = {t for t, x in by.items() if x["master"] == "second"}
    assert second and all(t.startswith(f"u{plant.units[1]} fc04") for t in second), by
    assert sum(x["requests"] for t, x in by.items() if x["master"] == "first") > f.evidence["its_requests"], by
    words = "\n".join(f.text_lines())
    assert "master second" in words and "{" not in words and "None" not in words, words


def test_new_kinds_parse():
    assert parse(["second_master_fc04:7", "timeout_mild:3"]) == (("second_master_fc04", 7), ("timeout_mild", 3))
    assert alarms([]) == []


def test_a_timeout_exceeded_by_the_slowest_answers_only_is_found_with_a_timeout_to_set():
    """timeout_mild: about 5 % of one unit's answers come after the master's timeout, after its retry (which the
    master takes them for); the unit's tail of answers in time comes close to the timeout."""
    results, advice = [], []
    for seed in SEEDS:
        plant = draw(seed)
        findings = diagnose_plant(plant, ["timeout_mild:{u1}"], seconds=60)
        results.append((plant.label(), ("timeout_too_short", plant.units[1]), findings))
        advice += [(f.evidence["recommended_timeout_ms"], plant.timeout_ms) for f in findings
                   if f.kind == "timeout_too_short"]
    t = tally(results)
    assert t["found"] >= FOUND_AT_LEAST * t["runs"], t["missed_runs"]
    assert t["false_alarms"] == 0, t["false_runs"]
    assert advice and all(set_ms > timeout for set_ms, timeout in advice), advice


def test_busy_healthy_plants_give_nothing_above_info():
    """Cycles back to back and drives started and stopped every second: no second master, no short timeout."""
    t = tally([(draw(s).label(), None, diagnose_plant(draw(s), (), seconds=30, **busy(draw(s)))) for s in SEEDS])
    assert t["false_alarms"] == 0, t["false_runs"]


def test_a_silent_unit_only_written_is_silent_and_its_retries_are_no_echoes():
    """A unit the master only writes (05, 06, 08: answered by an echo of the request) goes silent: the master's
    retries, byte for byte the request, are not paired as its echoes (the pairer tells them by their timing),
    and unit_silent names it; every echo of the units that answer is still paired."""
    from sniffer.capture.session import Session
    from sniffer.capture.settings import CaptureSpec
    from sniffer.simulator.scenario import PollSpec
    from sniffer.simulator.sources import SimulatedSource
    from helpers import diagnose_source

    wrong = missed = echoes = 0
    for seed in SEEDS:
        plant = draw(seed)
        silent = plant.units[1]
        others = tuple(u for u in plant.units if u != silent)
        polls = (PollSpec(0x03, 0x2100, 4, units=others), PollSpec(0x06, 0x2001),
                 PollSpec(0x05, 0x0001, every=2, value=0xFF00), PollSpec(0x08, 0x0000, every=3, value=0x1234))
        sc = apply(scenario(plant, polls=polls), [f"unit_silent:{silent}@10-40"])
        session = Session(CaptureSpec.of(), SimulatedSource(sc, sc.line, 50, seed, "wire"), [])
        session.open()
        for f in session:
            t = f.t_ns / 1e9 - session.info.t0_ns / 1e9
            if f.unit == silent and f.function in (5, 6, 8) and 10.5 < t < 40:
                wrong += f.role == "response"
            elif f.unit in others and f.function in (5, 6, 8) and f.role == "request" and f.crc_ok:
                echoes += 1
                missed += f.pair is None
        findings, _ = diagnose_source(SimulatedSource(sc, sc.line, 50, seed, "wire"))
        assert ("unit_silent", silent) in alarms(findings), (plant.label(), alarms(findings))
    assert wrong == 0 and echoes > 1000 and missed == 0, (wrong, echoes, missed)


@pytest.mark.parametrize("first,second", [("noise_correlated_with_load", "driver_enable_late"),
                                          ("driver_enable_late", "drive_fault"), ("latency_drift", "bus_unbiased")])
def test_two_causes_whose_damage_overlaps_are_both_found_fast(first, second):
    """The fast lane's share of test_diagnose_sweeps.py's two-cause sweep: the one seed of each pair that used to
    miss (one cause's damage over the other's signs)."""
    import dataclasses

    from plants import cause, diagnose, verdict

    p = cause(first, 0)
    q = cause(second, 50, base=dataclasses.replace(p, faults=(), expect=()))
    both = dataclasses.replace(q, faults=p.faults + q.faults, expect=p.expect + q.expect,
                               seconds=max(p.seconds, q.seconds))
    findings, _ = diagnose(both)
    found, false = verdict(both, findings)
    assert found and not false, (both.name, alarms(findings))
