"""`sniffer diff A B`: what changed between two captures (exit 0 nothing, 1 something, 2 error)."""

from __future__ import annotations

import sys

import os

from sniffer.analysis.diff import DiffReport, Summary, compare
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.flags import command_parser, decode_flags, input_format_flag, serial_flags


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "diff", help="what changed between two captures: units, polls, registers, errors, latency",
        description="""\
            What changed on a bus between two captures, said as a field engineer would: units that appeared or
            went quiet, polls that changed, registers written to other values, error and latency figures.
            Exit 0 nothing changed, 1 something did, 2 an error.""",
        examples=["sniffer diff commissioning.mcap today.mcap",
                  "sniffer diff before.mcap after.mcap --format json > changes.json"])
    p.add_argument("a", metavar="BEFORE", help="the capture before (e.g. at commissioning)")
    p.add_argument("b", metavar="AFTER", help="the capture after")
    p.add_argument("--format", choices=["text", "json"], default="text", help="output format")
    input_format_flag(p)
    serial_flags(p, "file")
    decode_flags(p, "file")


def run(spec: CaptureSpec, args) -> int:
    import orjson

    report = diff(args.a, args.b, spec.with_(input=None))
    if args.format == "json":
        sys.stdout.write(orjson.dumps(report.to_dict(), option=orjson.OPT_INDENT_2).decode() + "\n")
    else:
        sys.stdout.write(report.to_text())
    return 0 if report.same else 1


def summarize_capture(path, spec=None) -> dict:
    """Decode a capture file and summarise it as it decodes; CaptureError for unreadable or damaged input."""
    from sniffer.decoding import decode_file
    from sniffer.events import CaptureError

    session = decode_file(path, spec)
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
