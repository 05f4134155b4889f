"""Auto-identification: a unit's model guessed from its traffic; a user map wins; contradictions flagged."""

from __future__ import annotations

from helpers import bursts, fr, run_events

from sniffer.line import LineSettings

L = LineSettings(19200, "E", 1)




# status word 0001H (running) and input terminal S1 on (0001H): two values only A510's map explains
A510_POLL = [fr("020325200005"), fr("02030a00010000000113881386"), fr("020625020fa0"), fr("020625020fa0")]


def test_unmapped_unit_guessed_from_its_registers():
    frames = run_events(bursts(A510_POLL * 4, L), L)
    guesses = [f for f in frames if any(a.code == "model.guess" for a in f.annotations)]
    assert len(guesses) == 1
    note = next(a for a in guesses[0].annotations if a.code == "model.guess")
    assert "a510" in note.detail and "2520H" in note.detail
    assert frames[0].model == "generic"  # no guess from one request
    last = frames[-3]  # a read response after the guess
    assert last.model == "a510"
    assert {p["address"]: p["unit"] for p in last.points}[0x2524] == "Hz"


def test_user_map_wins_and_contradiction_is_annotated():
    frames = run_events(bursts(A510_POLL * 4, L), L, devices={2: "tds-v8"})
    assert all(f.model == "tds-v8" for f in frames)
    flagged = [f for f in frames if any(a.code == "model.mismatch" for a in f.annotations)]
    assert len(flagged) == 1
    assert "a510" in next(a.detail for a in flagged[0].annotations if a.code == "model.mismatch")


def test_generic_traffic_is_not_guessed():
    poll = [fr("0103000a0002"), fr("01030400010002")]
    frames = run_events(bursts(poll * 6, L), L)
    assert all(f.model == "generic" for f in frames)
