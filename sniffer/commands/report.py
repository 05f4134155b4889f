"""`sniffer report CAPTURE... --out report.html [--compare GOLDEN]`: a bus-health report (sniffer.report).

Each capture runs through its own capture session, in the order given, and the
report's collector takes the frames as they pass (flat memory).  Every input is
checked before the first one is decoded; the page is written as NAME.part and
renamed when complete, so a failed or interrupted run leaves no report behind.
A capture that is damaged but readable is reported on (the page says what was
lost) and the command ends with its error line and exit code 2, as replay does.
"""

from __future__ import annotations

import os

from sniffer.formats.outputs import Output, readable, shown
from sniffer.capture.settings import CaptureSpec
from sniffer.events import CaptureError
from sniffer.commands.common import EXIT_OK, jobs_for, report, say
from sniffer.commands.flags import (
    command_parser, decode_flags, input_format_flag, jobs_flag, progress_flag, serial_flags,
)
from sniffer.commands.replay import file_source
from sniffer.decoding import decode


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "report", help="a bus-health report of captures: one HTML file that opens offline",
        description="""\
            A bus-health report for the customer or the file: units and their poll rates, latency, errors and
            faults over time, register values, in one HTML file with its scripts inside (it opens offline,
            from a mail or a USB stick).  --compare adds what changed against a reference capture.""",
        examples=["sniffer report cabinet3.mcap --out cabinet3.html",
                  "sniffer report monday.mcap tuesday.mcap --compare commissioning.mcap --out week.html",
                  "sniffer report /var/lib/sniffer/cab3 --out cab3.html --progress"])
    p.add_argument("captures", nargs="+", metavar="CAPTURE",
                   help="capture files (MCAP, byte CSV, Saleae CSV, pcap/pcapng) or rotated captures' folders, "
                        "reported as one, in this order")
    input_format_flag(p)
    p.add_argument("--out", metavar="FILE.html",
                   help="the report to write (default: next to the first capture, its name with .html: "
                        "cab3.mcap -> cab3.html, a rotated capture's folder cab3/ -> cab3.html)")
    p.add_argument("--compare", metavar="GOLDEN",
                   help="a reference capture: the page adds what changed against it (as `sniffer diff GOLDEN ...`)")
    p.add_argument("--title", help="the page's title (default: Bus report: the captures' names)")
    progress_flag(p, "a progress bar per capture on stderr")
    jobs_flag(p)
    serial_flags(p, "file")
    decode_flags(p, "file")


def _check_input(spec: CaptureSpec, path: str, what: str = "") -> None:
    """An input that is missing, unreadable, not a capture, or needs flags it was not given fails now, before
    hours of decoding the ones before it (its header is read; the source names the problem)."""
    from sniffer.sources.segset import capture_source

    real, _ = readable(path)
    if not os.path.exists(real):
        raise CaptureError(f"{shown(path)}: no such file" + (f" ({what})" if what else ""))
    source = capture_source(real, spec.input_format)  # a file, or a rotated capture's folder or index
    try:
        spec.resolve(source.open())
    finally:
        source.close()


def default_report_path(capture: str) -> str:
    """Where a report goes without --out: beside the (first) capture, named after it."""
    path = os.path.normpath(capture)
    stem, ext = os.path.splitext(path)
    return (path if os.path.isdir(path) or not ext else stem) + ".html"


def run(spec: CaptureSpec, args) -> int:
    from sniffer.report import Collector, render

    captures = list(args.captures)
    golden = args.compare
    for path in captures:
        _check_input(spec, path)
    if golden:
        _check_input(spec, golden, "--compare")
    if not spec.out:
        spec = spec.with_(out=default_report_path(captures[0]))
    out = Output(spec.out, inputs=[*captures, *([golden] if golden else []), *spec.read_paths()])
    collector = Collector(compare=bool(golden))
    rc = EXIT_OK
    jobs = jobs_for(spec, args)
    try:
        for path in captures:
            cspec = spec.with_(input=path, inputs=(path,))  # one capture: a file or a rotated capture's segments
            source = file_source(cspec)
            session = decode(cspec, source, jobs=jobs, progress=path if args.progress else None)
            session.open()
            collector.begin(path, session)
            for f in session:  # by parts or not, every frame here, in order
                collector.frame(f)
            collector.end(session)
            rc = max(rc, report(session, label=path))
        data = collector.to_data()
        if golden:
            data["compare"] = _compare(collector, golden, captures, spec)
        title = args.title or f"Bus report: {', '.join(os.path.basename(p) for p in captures)}"
        page = render(data, title)
        out.write_text(page)
    except BaseException:
        out.discard()
        raise
    out.commit()
    frames = data["totals"]["frames"]
    say(f"wrote {out.path} ({len(page.encode()):,} bytes: {frames:,} frames from {len(captures)} capture(s))")
    return rc


def _compare(collector, golden: str, captures: list[str], spec: CaptureSpec) -> dict:
    """The semantic diff of the golden capture (before) against the captures of this report (after)."""
    from sniffer.analysis.diff import compare
    from sniffer.commands.diff import summarize_capture

    before = summarize_capture(golden, spec.with_(input=None))
    d = compare(before, collector.summary.to_dict(), golden, " + ".join(captures))
    return {"golden": golden, "same": d.same, "text": d.to_text(), "diff": d.to_dict()}
