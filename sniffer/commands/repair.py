"""`sniffer repair FILE`: a finished copy of an MCAP capture that was cut short or damaged."""

from __future__ import annotations

import os

from sniffer.formats.mcap.repair import default_output, repair
from sniffer.formats.outputs import Output, readable, shown
from sniffer.capture.settings import CaptureSpec
from sniffer.events import CaptureError
from sniffer.commands.common import EXIT_OK, say
from sniffer.commands.flags import command_parser


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "repair", help="make a truncated (killed) or damaged capture readable by any MCAP reader",
        description="""\
            A clean copy of an MCAP capture that was cut short (power lost, process killed: FILE.part) or
            damaged: every complete record kept, the summary and index written again.  `sniffer replay`
            reads such a file without it; other MCAP readers (Foxglove) need the copy.""",
        examples=["sniffer repair cabinet3.mcap.part              # writes cabinet3.mcap",
                  "sniffer repair damaged.mcap -o fixed.mcap"])
    p.add_argument("file", help="the capture (FILE.mcap, or FILE.mcap.part that a killed capture left)")
    p.add_argument("-o", "--out", help="output file (default: FILE.repaired.mcap; NAME.mcap for NAME.mcap.part)")


def run(spec: CaptureSpec, args) -> int:
    src, note = readable(args.file)
    if not os.path.exists(src):
        raise CaptureError(f"{shown(src)}: no such file")
    if note:
        say(f"note: {note}")
    path = spec.out or default_output(args.file)
    # a killed capture's NAME.part finished as NAME: its own name, not an input (the part file stays)
    own_name = os.path.abspath(path) + ".part" == os.path.abspath(src)
    out = Output(path, inputs=[] if own_name else [src], what="--out")
    try:
        st = repair(src, out.part)
    except BaseException:
        out.discard()
        raise
    out.commit()
    problem = f" ({st['problem']})" if st.get("problem") else ""
    say(f"wrote {out.path}: {st['messages']} message(s) kept, {st['bytes_dropped']} bytes dropped{problem}")
    return EXIT_OK
