"""`sniffer diagnose CAPTURE... [--bus FILE] [--format text|json] [--params REFERENCE]`: findings, most severe first.

The capture (a file, a rotated capture's folder, several files read as one, as `replay` reads them) runs
through one capture session; the diagnosis engine (sniffer.diagnose) takes the frames as they pass, in
flat memory, and gives its findings at the end: text for people, `{"findings": [...]}` for scripts.
A damaged but readable capture is diagnosed (the findings say what was read) and the command ends with
its error line and exit code 2, as replay does.
"""

from __future__ import annotations

import sys

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import jobs_for, report
from sniffer.commands.flags import command_parser, decode_flags, input_flags, jobs_flag, progress_flag, serial_flags
from sniffer.commands.replay import file_source
from sniffer.decoding import decode


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "diagnose", help="what is wrong on the line, why, and what to do: findings from a capture, "
                                     "most severe first (docs/diagnose.md)",
        description="""\
            Read a capture (a file, a rotated capture's folder, several files as one) and say what is wrong on
            the line: each finding with its kind, severity, link and unit, the time span, the evidence in
            numbers (the frames to look at by number), one sentence and what to do.  Text for people, JSON
            {"findings": [...]} for scripts.""",
        examples=["sniffer diagnose cabinet3.mcap",
                  "sniffer diagnose /var/lib/sniffer/cab3 --bus plant.toml --format json",
                  "sniffer diagnose today.mcap --params saved-params.csv"])
    input_flags(p)
    p.add_argument("--format", choices=["text", "json"], default="text",
                   help='text for people, or JSON {"findings": [...]} for scripts (default: text)')
    p.add_argument("--params", metavar="REFERENCE",
                   help="a drive's saved parameter set (CSV: unit,register,value) or an earlier capture: "
                        "parameters this capture reads otherwise are a finding")
    progress_flag(p)
    jobs_flag(p)
    serial_flags(p, "file")
    decode_flags(p, "file")


def _settings(session) -> str:
    """Where the frames were read: the line's settings, or each link's."""
    links = getattr(session.pipeline, "resolved", None)
    if isinstance(links, dict) and len(links) > 1:
        each = ", ".join(f"{name} at {r.describe()}" for name, r in links.items())
        return f"on {len(links)} links ({each})"
    return f"at {session.resolved.describe()}"


def run(spec: CaptureSpec, args) -> int:
    from sniffer.diagnose import Diagnosis, summary, to_json, to_text
    from sniffer.diagnose.reference import load

    reference = load(args.params, spec.with_(input=None, inputs=())) if args.params else None
    source = file_source(spec)
    engine = Diagnosis(reference)
    session = decode(spec, source, jobs=jobs_for(spec, args), progress=spec.input if args.progress else None)
    session.open()
    engine.start_session(session)
    frame = engine.frame
    for f in session:  # by parts or not, every frame here, in order
        frame(f)
    findings = engine.findings()
    for line in reference.notes() if reference is not None else ():
        print(f"sniffer: note: {line}", file=sys.stderr)
    if args.format == "json":
        sys.stdout.write(to_json(findings))
    else:
        what = " + ".join(spec.inputs or [spec.input])
        head = f"sniffer diagnose {what}: {session.frames_out:,} frames {_settings(session)}; {summary(findings)}\n"
        sys.stdout.write(to_text(findings, head, session.frames_out))
    return report(session, label=spec.input)
