"""line_damage: frames damaged on a link that no other finding explains.

The kinds that name a cause of damage (wrong settings, a second master's collisions, a driver's timing,
a floating line, interference with a drive's load) each need their own evidence; a line can carry damage
none of them recognise (a bad splice, a missing termination at one end, a transceiver failing).  Saying
nothing then reads as "the line is fine".  So when a link has at least MIN_DAMAGED damaged frames and at
least MIN_SHARE of its frames, and no finding on it names a cause, this says how much, when, and where:
the unit whose answers carry most of it (a damaged answer is still paired to its request, or falls where
the unit's answer was due).  It reads what the engine counts for every frame (state.Link, state.Unit).
"""

from __future__ import annotations

from sniffer.codes import WARNING
from sniffer.diagnose.finding import Finding

MIN_DAMAGED = 10
MIN_SHARE = 0.01  # of the link's frames: a CRC error in a thousand is the odd spike, not a finding
MOSTLY = 0.8  # one unit's answers hold this share of the damaged answers: it is named
EXPLAINS = frozenset({"wrong_line_settings", "second_master", "driver_enable_late", "driver_disable_early",
                      "bus_unbiased", "noise_correlated_with_load"})
ACTION = ("Check the cable and its connections (A and B not swapped or loose, a twisted pair, the shield grounded at "
          "one end), a 120 ohm termination at both ends and nowhere else, and what runs beside the line; a logic "
          "analyzer's capture of the levels (sniffer live sigrok:DRIVER) shows what the bytes cannot")


def unexplained(found: list[Finding], d) -> list[Finding]:
    """The line_damage findings of the links where no finding names a cause of their damage."""
    explained = {f.link for f in found if f.kind in EXPLAINS}
    out = []
    for name, link in d.links.items():
        n, crc, noise = link.frames, link.crc_bad, link.noise_frames
        bad = crc + noise
        if name in explained or bad < MIN_DAMAGED or bad < MIN_SHARE * n:
            continue
        answers = {u: x.garbled + x.damaged_answers for u, x in link.units.items() if x.garbled + x.damaged_answers}
        where = ""
        if answers:
            top = max(answers, key=answers.get)
            if answers[top] >= MOSTLY * sum(answers.values()) and answers[top] >= MIN_DAMAGED // 2:
                where = f"; {answers[top]} of them are unit {top}'s answers (the other units' are nearly intact)"
        text = (f"{bad} of {n} frames damaged ({bad / n:.1%}: {crc} with a bad checksum, {noise} noise bursts)"
                f"{where}, and no cause could be told from the bytes")
        episodes = link.damage.episodes(d.seconds, "damaged frames")
        out.append(Finding("line_damage", WARNING, text, ACTION, link=name,
                           t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns), episodes=episodes,
                           evidence={"frames": n, "damaged": bad, "bad_checksum": crc, "noise_bursts": noise,
                                     "damaged_answers_by_unit": {str(u): c for u, c in sorted(answers.items())}}))
    return out
