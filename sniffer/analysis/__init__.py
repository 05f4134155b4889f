"""What a capture says, as Textual-free models the TUI, the report, `check`, `diff`, `learn` and MQTT share.

    check.py          the golden text of frames, compared line by line (`sniffer check`)
    checksummary.py   what a failing check says first (frames differing, first difference, by unit and field)
    goldenfields.py   a golden line's fields, and the --ignore / --tolerance rules they are compared with
    diff.py           a capture's summary (units, polls, registers, latency) and two compared (`sniffer diff`)
    learn.py          a skeleton register map from traffic (`sniffer learn`)
    unitfigures.py    per-unit figures, each defined once;  flags.py  a frame's problem bits
    register_book.py  each unit's registers: latest values, names, history;  history.py  a register's samples
    reads.py          reads as the port delivered them, with the frames their bytes went to
    linehealth.py     most frames bad: the line settings are probably wrong (stderr and the TUI say it once)
"""

from sniffer import face

_EXPORTS = {
    "golden_text": "sniffer.analysis.check",
    "compare_text": "sniffer.analysis.check",
    "Tolerances": "sniffer.analysis.check",
    "Summary": "sniffer.analysis.diff",
    "compare": "sniffer.analysis.diff",
    "Learner": "sniffer.analysis.learn",
    "UnitFigures": "sniffer.analysis.unitfigures",
    "UnitBook": "sniffer.analysis.unitfigures",
    "Latencies": "sniffer.analysis.unitfigures",
    "frame_flags": "sniffer.analysis.flags",
    "RegisterBook": "sniffer.analysis.register_book",
    "Series": "sniffer.analysis.history",
    "ReadMarker": "sniffer.analysis.reads",
}
__all__ = sorted(_EXPORTS)
__getattr__ = face(__name__, _EXPORTS)
