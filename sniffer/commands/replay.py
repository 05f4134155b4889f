"""`sniffer replay FILE...`: a capture file decoded again, with today's decoders and the flags given."""

from __future__ import annotations

import sys

from sniffer.capture.session import Session
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
        session = Session(spec, source, [sink])
        session.open()
        note_unfinished(session)
        rc = run_session_tui(session, sink, source_label=spec.input, source_path=spec.input)
        return rc or report(session, label=spec.input)
    jobs = jobs_for(spec, args)
    if jobs > 1 and spec.stream != "pcapng":  # one pcapng stream: its header once, then packets in order
        return _parallel(spec, source, args, jobs)
    bar = None
    sinks = [s for s in (stream_sink(spec, line_buffered=False),) if s is not None]
    session = Session(spec, source, [line_warning(file=spec.input), *sinks])
    if args.progress:
        from sniffer.capture.progress import ReplayProgress

        bar = ReplayProgress(spec.input, source=source, frames=lambda: session.frames_out)
        session.on_event = bar.update
    try:
        session.open()
        note_unfinished(session)
        session.run()
    finally:
        if bar is not None:
            bar.close()
    if getattr(source, "unfinished", None):
        note_unfinished(session)  # a set's segments are read only as the replay reaches them
    return report(session, label=spec.input)


def _parallel(spec: CaptureSpec, source, args, jobs: int) -> int:
    """replay --jobs N: the capture decoded by parts in N processes (sniffer.parallel), the same lines; the line
    warning counts every frame, in order, here (from a few numbers a frame the workers send: HealthPlan)."""
    from sniffer.commands.common import parallel_run, run_with_bar
    from sniffer.parallel.outputs import HealthPlan, HealthWriter, StreamPlan, StreamWriter, stdout_for

    outputs = [(StreamPlan(spec.stream), StreamWriter(stdout_for(spec.stream)))] \
        if spec.stream in ("text", "jsonl") else []
    outputs.append((HealthPlan(), HealthWriter(line_warning(file=spec.input))))
    run = parallel_run(spec, source, outputs, jobs, spec.input if args.progress else None)
    run.open()
    note_unfinished(run.session)
    run_with_bar(run)
    if getattr(source, "unfinished", None):
        note_unfinished(run.session)
    return report(run, label=spec.input)


def _rotate(spec: CaptureSpec, source) -> int:
    """replay --rotate --out FOLDER: the capture written again as segments, as a live capture writes them."""
    from sniffer.commands.common import capture_sinks, destination, summary_line

    sinks = capture_sinks(spec, spec.input, inputs=spec.inputs or [spec.input], line_buffered=False,
                          timed_flush=False)
    session = Session(spec, source, [line_warning(file=spec.input), *sinks], label=f"replay {spec.input}")
    session.open()
    say(f"replaying {spec.input}{destination(spec, session)}")
    session.run()
    note_unfinished(session)
    print(summary_line(session), file=sys.stderr)
    return report(session, label=spec.input)


def unfinished_paths(session: Session) -> list[str]:
    """The input files of `session` (or a parallel run's) not closed cleanly, as read so far."""
    session = getattr(session, "session", session)
    paths = list(getattr(session.source, "unfinished", None) or ())
    if not paths and session.info is not None and session.info.extra.get("mcap_unfinished"):
        paths = [session.spec.input]
    return paths


def note_unfinished(session: Session) -> None:
    """A note for each input file not closed cleanly, once: called when the session opens, and again when it
    ends (a rotated capture's segments are opened only as the reading reaches them)."""
    paths = unfinished_paths(session)
    session = getattr(session, "session", session)
    said = session.__dict__.setdefault("unfinished_said", set())
    for path in paths:
        if path in said:
            continue
        said.add(path)
        say(f"note: {path} was not closed cleanly (capture killed, or still being written?); read up to its last "
            f"complete record. 'sniffer repair {path}' writes a clean copy.")


def frames_by_parts(spec: CaptureSpec, source, jobs: int, label: str | None, begin, frame):
    """A capture decoded by parts in `jobs` processes (sniffer.parallel) for a command that must see every frame
    in one place (a report, a diagnosis): `begin(run)` once it is open, then `frame(f)` for each frame in
    capture order, as from one session; `label`: a progress bar on stderr.  The run, ended, for the report."""
    from sniffer.commands.common import parallel_run
    from sniffer.parallel.outputs import FramesPlan

    run = parallel_run(spec, source, [], jobs, label)
    try:
        run.open()
        note_unfinished(run.session)
        begin(run)
        for part in run.parts([FramesPlan()]):
            for f in part.pieces[0]:
                frame(f)
    finally:
        if run.bar is not None:
            run.bar.close()
    note_unfinished(run.session)  # a rotated capture's segments are opened as the reading reaches them
    return run
