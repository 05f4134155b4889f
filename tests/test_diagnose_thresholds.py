"""Thresholds from the physics: a biased line's idle level is held, so stray bursts out of it are reportable even
when they are few and no frame is damaged (the rate is stated); a line with frame damage about is not blamed
on bias for the noise that damage brings."""

from __future__ import annotations

from test_diagnose import diagnose_sim, worst


def test_strays_after_0_7_percent_of_transmissions_are_bus_unbiased_with_their_rate():
    findings, _ = diagnose_sim("default", ("bus_unbiased,0.007",), 120.0, seed=5)
    (f,) = [x for x in findings if x.kind == "bus_unbiased"]
    assert f.severity == "warning" and f.evidence["frames_crc_bad"] == 0
    assert 0.002 < f.evidence["per_frame"] < 0.015 and f.evidence["per_hour"] > 100
    assert "an hour" in f.text
    assert worst(findings) == [("bus_unbiased", None)]


def test_noise_that_comes_with_damaged_frames_is_not_blamed_on_bias():
    findings, _ = diagnose_sim("errors", (), 60.0)
    assert "bus_unbiased" not in {f.kind for f in findings}


def test_a_full_line_is_not_nothing_to_fix_and_a_warning_once_it_stretches():
    findings, _ = diagnose_sim("stress", (), 20.0, "wire")
    (f,) = [x for x in findings if x.kind == "poll_cycle"]
    assert f.evidence["line_busy_share"] >= 0.95 and f.evidence["room_for_units"] == 0
    assert f.severity == "info" and "Nothing to fix" not in f.action and "no room" in f.text
    findings, _ = diagnose_sim("stress", ("timeout_too_short:2",), 20.0, "wire")
    (f,) = [x for x in findings if x.kind == "poll_cycle"]
    assert f.severity == "warning" and f.evidence["retries_and_unanswered"] > 0


def test_a_quiet_line_has_nothing_to_fix():
    findings, _ = diagnose_sim("tds-v8", (), 20.0, "wire", params=("unit1.trip_every_s=(0.0, 0.0)",))
    (f,) = [x for x in findings if x.kind == "poll_cycle"]
    assert f.severity == "info" and f.action.startswith("Nothing to fix") and f.evidence["line_busy_share"] < 0.7


def test_a_register_refused_at_every_poll_is_a_warning_naming_the_register():
    findings, _ = diagnose_sim("tds-v8", (), 40.0)
    (f,) = [x for x in findings if x.kind == "unit_refuses" and x.unit == 1]
    assert f.severity == "warning" and "Cn-27 Communication Fault Detection Time" in f.text
