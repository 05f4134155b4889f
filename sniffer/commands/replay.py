"""`sniffer replay FILE...`: a capture file decoded again, with today's decoders and the flags given."""

from __future__ import annotations

import sys

from sniffer.decoding import decode, note_unfinished, unfinished_paths  # noqa: F401 - the commands' names
from sniffer.capture.settings import CaptureSpec
from sniffer.sources.segset import replay_source as file_source  # noqa: F401 - the commands' name for it
from sniffer.commands.common import UsageError, jobs_for, line_warning, report, say, stream_sink
from sniffer.commands.flags import (
    command_parser, decode_flags, foxglove_flags, input_flags, jobs_flag, mqtt_flags, progress_flag, serial_flags,
    stream_flags, trigger_flags, unattended_flags,
)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "replay", help="decode a capture file (MCAP, byte CSV, Saleae CSV, pcap, sigrok .sr)",
        description="""\
            Decode a capture again, as `live` decoded it: frame lines on stdout, or the TUI (--tui).  An MCAP
            says its own settings and drive models; flags override them (a byte CSV carries none: give
            --baud).  With --trigger the windows are cut from the capture, as `live` would have cut them.""",
        examples=["sniffer replay cabinet3.mcap",
                  "sniffer replay cabinet3.mcap --tui",
                  "sniffer replay capture.bytes.csv --baud 9600 --parity N --format jsonl",
                  "sniffer replay /var/lib/sniffer/cab3 --quiet --trigger fault --pre 2m --windows faults/"])
    input_flags(p)
    jobs_flag(p)
    progress_flag(p)
    p.add_argument("--tui", action="store_true", help="browse the capture in the terminal UI")
    serial_flags(p, "file")
    decode_flags(p, "file")
    stream_flags(p, quiet="only what --trigger, --rotate or --mqtt write")
    p.add_argument("--out", metavar="FOLDER", help="with --rotate: write the capture again as segments in FOLDER")
    unattended_flags(p)
    trigger_flags(p)
    foxglove_flags(p)
    mqtt_flags(p)



def run(spec: CaptureSpec, args) -> int:
    if (spec.rotate is None) != (spec.out is None):
        raise UsageError("replay writes a capture again only as segments: give --rotate and --out FOLDER together "
                         "(one file: sniffer export --to mcap)")
    source = file_source(spec)
    if spec.rotate is not None:
        return _rotate(spec, source)
    if args.tui:
        if not (sys.stdout.isatty() and sys.stdin.isatty()):
            raise UsageError("replay --tui needs a terminal (stdin and stdout); without one, leave out --tui")
        from sniffer.tui.run import run_session_tui
        from sniffer.tui.sink import TuiSink

        sink = TuiSink()
        session = decode(spec, source, [sink])
        session.open()
        rc = run_session_tui(session, sink, source_label=spec.input, source_path=spec.input)
        return rc or report(session, label=spec.input)
    sinks = [s for s in (stream_sink(spec, line_buffered=False),) if s is not None]
    run = decode(spec, source, [line_warning(file=spec.input), *sinks], jobs=jobs_for(spec, args),
                 progress=spec.input if args.progress else None)
    run.open()
    run.run()
    return report(run, label=spec.input)


def _rotate(spec: CaptureSpec, source) -> int:
    """replay --rotate --out FOLDER: the capture written again as segments, as a live capture writes them."""
    from sniffer.commands.common import capture_sinks, destination, summary_line

    sinks = capture_sinks(spec, spec.input, inputs=spec.inputs or [spec.input], line_buffered=False,
                          timed_flush=False)
    session = decode(spec, source, [line_warning(file=spec.input), *sinks], label=f"replay {spec.input}")
    session.open()
    say(f"replaying {spec.input}{destination(spec, session)}")
    session.run()
    print(summary_line(session), file=sys.stderr)
    return report(session, label=spec.input)
