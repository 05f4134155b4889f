"""The commands: each a few lines that pick a source and sinks and run a sniffer.capture.session.Session.

    capture.py   live, demo          replay.py   replay, decode
    simulate.py  simulate            export.py   export
    check.py     check               diff.py     diff
    repair.py    repair              view.py     attach, serve
    learn.py     learn               detect.py   detect
    status.py    status              dataset.py  export --to dataset, ingest
    query.py     query               report.py   report
    diagnose.py  diagnose
    common.py    what they share: the stdout stream, the capture's sinks, the end-of-run report

cli.py parses the flags into a CaptureSpec and calls `COMMANDS[name](spec, args)`.
"""

from __future__ import annotations

import importlib

_WHERE = {
    "live": "capture", "demo": "capture", "replay": "replay", "decode": "replay", "simulate": "simulate",
    "export": "export", "check": "check", "diff": "diff", "repair": "repair", "attach": "view", "serve": "view",
    "learn": "learn", "detect": "detect", "status": "status", "ingest": "dataset", "query": "query",
    "report": "report", "diagnose": "diagnose",
}
NAMES = tuple(_WHERE)


def command(name: str):
    """The function that runs command `name` (imported when used: `sniffer decode` need not load pyarrow)."""
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), f"cmd_{name}")
