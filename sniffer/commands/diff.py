"""`sniffer diff A B`: what changed between two captures (exit 0 nothing, 1 something, 2 error)."""

from __future__ import annotations

import sys

import os

from sniffer.analysis.diff import DiffReport, Summary, compare
from sniffer.capture.settings import CaptureSpec


def cmd_diff(spec: CaptureSpec, args) -> int:
    import orjson

    report = diff(args.a, args.b, spec.with_(input=None))
    if args.format == "json":
        sys.stdout.write(orjson.dumps(report.to_dict(), option=orjson.OPT_INDENT_2).decode() + "\n")
    else:
        sys.stdout.write(report.to_text())
    return 0 if report.same else 1


def summarize_capture(path, spec=None) -> dict:
    """Decode a capture file and summarise it as it decodes; CaptureError for unreadable or damaged input."""
    from sniffer.capture.session import decode_capture
    from sniffer.events import CaptureError

    session = decode_capture(path, spec)
    s = Summary()
    for f in session:
        s.add(f)
    if session.error:
        raise CaptureError(session.error)
    if session.damage:
        raise CaptureError(f"{session.damage[0]} (input damaged: {len(session.damage)} problem(s))")
    return s.to_dict()


def diff(a, b, spec=None, spec_b=None) -> DiffReport:
    """Semantic diff of two captures (decoded with the same settings unless spec_b), one after the other."""
    return compare(summarize_capture(a, spec), summarize_capture(b, spec_b or spec), os.fspath(a), os.fspath(b))
