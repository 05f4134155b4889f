"""Findings carry their episodes (from, to, how often), judged in windows of time: a unit silent for 40 s in
the middle of a capture is found though it answers before and after; a cause that comes twice gives two
episodes; the text, the JSON, the HTML report and the TUI's Verdicts tab say so in words."""

from __future__ import annotations

import json

from sniffer.diagnose import to_json, to_text
from sniffer.diagnose.episodes import Windows

from test_diagnose import diagnose_sim


def _one(findings, kind, unit=None):
    got = [f for f in findings if f.kind == kind and (unit is None or f.unit == unit)]
    assert len(got) == 1, [(f.kind, f.unit) for f in findings]
    return got[0]


def test_a_unit_silent_for_40_s_mid_capture_is_found_with_its_span():
    findings, _ = diagnose_sim("default", ("unit_silent:5@20-60",), 80.0)
    f = _one(findings, "unit_silent", 5)
    assert f.severity == "error"
    (e,) = f.episodes
    assert 19.5 < e.from_s < 21.0 and 59.0 < e.to_s < 61.0 and e.count >= 100
    assert [x for x in findings if x.severity != "info" and x.kind != "unit_silent"] == []


def test_a_silence_that_comes_twice_is_two_episodes():
    findings, _ = diagnose_sim("default", ("unit_silent:2@10-18", "unit_silent:2@40-48"), 60.0)
    f = _one(findings, "unit_silent", 2)
    assert [(round(e.from_s), round(e.to_s)) for e in f.episodes] == [(10, 18), (40, 48)]
    assert f.episode_count == 2


def test_strays_that_come_twice_are_two_episodes():
    findings, _ = diagnose_sim("default", ("bus_unbiased@10-20", "bus_unbiased@40-50"), 60.0)
    f = _one(findings, "bus_unbiased")
    assert [(round(e.from_s), round(e.to_s)) for e in f.episodes] == [(10, 20), (40, 50)]


def test_a_steady_cause_is_one_episode_over_the_capture():
    w = Windows()
    for i in range(6000):  # 60 s, a frame each 10 ms, every 50th damaged
        w.add(i * 10_000_000, i % 50 == 0)
    (e,) = w.episodes(lambda t: t / 1e9, "damaged frames")
    assert e.from_s == 0.0 and e.to_s >= 59.0 and e.count == 120


def test_episodes_are_words_in_text_json_report_and_tui(tmp_path):
    from sniffer.report.page import _verdicts
    from sniffer.tui.verdicts import detail_text

    findings, _ = diagnose_sim("default", ("unit_silent:2@10-18", "unit_silent:2@40-48"), 60.0)
    text = to_text(findings)
    assert "when: 2 episodes: 10.0-18.0 s (" in text.replace("10.1-", "10.0-") or "when: 2 episodes:" in text
    doc = json.loads(to_json(findings))
    (f,) = [x for x in doc["findings"] if x["kind"] == "unit_silent"]
    assert len(f["episodes"]) == 2 and f["episodes"][0]["what"] == "requests unanswered"
    html = _verdicts(doc)
    assert "when: 2 episodes" in html
    tui = detail_text(_one(findings, "unit_silent", 2)).plain
    assert "when: 2 episodes" in tui
    for out in (text, html, tui):
        assert "None" not in out and "{'" not in out and "[{" not in out


def test_drive_trips_are_episodes_not_python_in_the_evidence():
    findings, _ = diagnose_sim("a510", (), 40.0)
    f = next(x for x in findings if x.kind == "drive_fault")
    assert f.episodes and f.episode_count >= len(f.episodes)
    text = "\n".join(f.text_lines())
    assert "None" not in text and "{" not in text and "[" not in text
    assert "when: " in text


def _spans(f) -> list[tuple[int, int]]:
    return [(round(e.from_s), round(e.to_s)) for e in f.episodes]


def test_a_driver_cut_in_one_span_is_one_episode_over_it():
    for kind in ("driver_enable_late", "driver_disable_early"):
        findings, _ = diagnose_sim("default", (f"{kind}:2@10-25",), 40.0)
        f = _one(findings, kind, 2)
        assert _spans(f) == [(10, 25)], (kind, f.episodes)
        assert "when: 1 episode: 10.0-25.0 s (" in "\n".join(f.text_lines()), kind


def test_a_driver_cut_that_comes_twice_is_two_episodes_in_words():
    for kind, what in (("driver_enable_late", "first"), ("driver_disable_early", "last")):
        findings, _ = diagnose_sim("default", (f"{kind}:2@8-16", f"{kind}:2@30-38"), 45.0)
        f = _one(findings, kind, 2)
        assert _spans(f) == [(8, 16), (30, 38)], (kind, f.episodes)
        text = to_text(findings)
        assert "when: 2 episodes: 8.0-16.0 s (" in text and f"answers with the {what} byte damaged)" in text


def test_a_driver_cut_all_along_is_one_episode_over_the_capture():
    findings, _ = diagnose_sim("default", ("driver_enable_late:2",), 30.0)
    (e,) = _one(findings, "driver_enable_late", 2).episodes
    assert e.from_s < 1.0 and e.to_s > 29.0


def test_requests_refused_in_one_span_are_one_episode_over_it():
    findings, _ = diagnose_sim("default", ("unit_refuses:2@10-25",), 40.0)
    f = _one(findings, "unit_refuses", 2)
    assert _spans(f) == [(10, 25)] and f.episodes[0].count >= 100
    assert "when: 1 episode: 10.1-25.2 s (" in "\n".join(f.text_lines()) or "when: 1 episode: 10." in to_text(findings)


def test_requests_refused_twice_are_two_episodes_in_words():
    findings, _ = diagnose_sim("default", ("unit_refuses:2@8-16", "unit_refuses:2@30-38"), 45.0)
    f = _one(findings, "unit_refuses", 2)
    assert _spans(f) == [(8, 16), (30, 38)]
    assert "when: 2 episodes: 8.0-16.1 s (" in to_text(findings) and "requests refused)" in to_text(findings)


def test_a_register_refused_all_along_is_one_episode():
    findings, _ = diagnose_sim("tds-v8", (), 40.0)
    f = _one(findings, "unit_refuses", 1)
    (e,) = f.episodes  # a write refused at each of its polls, some seconds apart: one episode, all of them
    assert e.count == f.evidence["requests_refused"] and e.to_s - e.from_s > 30.0
    f = _one(findings, "unit_refuses", 2)  # (7 of its 10 reads refused: most of the time, and when)
    assert f.episodes and sum(e.count for e in f.episodes) == f.evidence["requests_refused"]


def test_retries_in_one_span_are_one_episode_of_the_storm():
    findings, _ = diagnose_sim("a510", ("unit_silent:1@6-30",), 40.0)
    f = _one(findings, "retry_storm")
    assert _spans(f) == [(6, 30)] and f.episodes[0].what == "retries"


def test_retries_that_come_twice_are_two_episodes_in_words():
    findings, _ = diagnose_sim("a510", ("unit_silent:1@4-16", "unit_silent:1@24-36"), 40.0)
    f = _one(findings, "retry_storm")
    assert _spans(f) == [(4, 16), (24, 36)]
    assert "when: 2 episodes: 4.0-16.0 s (" in to_text(findings) and " retries), 24.0-36.0 s (" in to_text(findings)


def test_a_latency_drift_is_an_episode_from_where_it_left_to_the_end():
    findings, engine = diagnose_sim("default", ("latency_drift:1",), 30.0, "wire")
    f = _one(findings, "latency_drift", 1)
    (e,) = f.episodes  # it grows all along: it has left the start by a quarter of the drift some seconds in
    assert 3.0 < e.from_s < 20.0 and e.to_s > 29.0 and "slower than at the start" in e.what
    assert e.count < engine.links[""].units[1].lat.n
    assert "when: 1 episode: " in "\n".join(f.text_lines())


def test_every_kind_found_says_when_in_episodes():
    """The kinds judged over the whole capture say when too: broadcasts answered, saves, writes not saved, a line
    read at the wrong settings, a unit that never answers, the poll cycle and its redundant reads (one episode
    over the span where it is a state, not events); each episode in words, nothing of Python's."""
    cases = [("errors", (), ()), ("tds-v8", ("eeprom_wear:2",), ()), ("tds-v8", ("params_not_saved:2",), ()),
             ("default", ("wrong_line_settings:38400",), ()), ("default", (), ("poll_period_ms=0",))]
    seen = set()
    for scenario, faults, params in cases:
        findings, _ = diagnose_sim(scenario, faults, 60.0, "wire", params=params)
        for f in findings:
            seen.add(f.kind)
            assert f.episodes and f.episode_count >= len(f.episodes), (scenario, f.kind, f.unit)
            for e in f.episodes:
                # (a trip's count is the master's writes meanwhile: none is a count too)
                assert 0.0 <= e.from_s <= e.to_s <= 62.0 and (e.count > 0 or f.kind == "drive_fault"), (f.kind, e)
            words = f.when()
            assert words and not any(x in words for x in ("None", "{", "[")), words
    assert {"answers_broadcast", "eeprom_wear", "params_not_saved", "wrong_line_settings", "unit_silent",
            "poll_cycle", "poll_redundant"} <= seen, seen
