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
