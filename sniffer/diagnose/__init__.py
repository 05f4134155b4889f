"""`sniffer diagnose`: from frames to verdicts, what is wrong on the line, why, and what to do.

    d = Diagnosis(reference)            # engine.py: frames in (capture order), findings out
    d.start_session(session)
    for f in session: d.frame(f)
    findings = d.findings()             # finding.Finding, most severe first
    to_json(findings) / to_text(findings)

    kinds.py     the kinds of finding (one table)      finding.py  a finding, its text and JSON
    engine.py    what every group needs, the dispatch  stats.py    quantiles, trends, tests
    line.py      wrong_line_settings                   wiring.py   driver_enable_late / _disable_early, bus_unbiased
    units.py     unit_silent, unit_refuses, answers_broadcast
    timing.py    timeout_too_short, latency_drift      masters.py  second_master, retry_storm
    drives.py    drive_fault                           correlate.py  noise_correlated_with_load
    episodes.py  when: windows of time, episodes
    when.py      episodes of retry_storm and latency_drift (judged over the capture by their groups)
    params.py    params_not_saved, eeprom_wear, params_changed (reference.py: --params)
    polls.py     poll_cycle, poll_redundant

Textual-free and sans-I/O: the command, the HTML report, the TUI and `check` all feed one.
"""

from __future__ import annotations

import json

from sniffer.diagnose.engine import Diagnosis
from sniffer.diagnose.finding import Finding, sort
from sniffer.diagnose.kinds import BY_NAME, KINDS

__all__ = ["Diagnosis", "Finding", "KINDS", "BY_NAME", "sort", "to_json", "to_text", "summary"]


def to_json(findings: list[Finding]) -> str:
    return json.dumps({"findings": [f.to_dict() for f in findings]}, indent=2, allow_nan=False, default=str) + "\n"


def summary(findings: list[Finding]) -> str:
    """'2 errors, 1 warning, 3 notes' (or 'no finding')."""
    n = {s: sum(1 for f in findings if f.severity == s) for s in ("error", "warning", "info")}
    parts = [f"{n['error']} error{'s' * (n['error'] != 1)}", f"{n['warning']} warning{'s' * (n['warning'] != 1)}",
             f"{n['info']} note{'s' * (n['info'] != 1)}"]
    return ", ".join(parts) if findings else "no finding"


def to_text(findings: list[Finding], head: str = "", frames: int | None = None) -> str:
    """The findings for people; `frames` read (None: not said) tells "nothing wrong" from "nothing read"."""
    lines = [head] if head else []
    if not findings:
        lines.append("No finding: nothing on this line looks wrong." if frames != 0 else
                     "No finding: no frame was read, so nothing could be judged.")
    for f in findings:
        lines += f.text_lines() + [""]
    return "\n".join(lines).rstrip("\n") + "\n"
