"""What the commands share: exit codes, the stdout stream, a capture's sinks, the end-of-run report."""

from __future__ import annotations

import sys

from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.flags import UsageError  # noqa: F401 - the commands' usage error, re-exported
from sniffer.formats import FileSink
from sniffer.stderr import say  # noqa: F401 - the commands' one line on stderr
from sniffer.parallel.options import jobs_for  # noqa: F401 - the commands' name for it
from sniffer.capture.summary import default_capture_name, summary_line, written  # noqa: F401 - re-exported

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
POSIX_TTY = ("termios", "fcntl")  # what reading a serial port or a pseudo-terminal takes here


def need_posix_tty(what: str) -> None:
    """One line (exit 2) where `what` cannot run: no POSIX terminal interface (Windows, some containers).
    The offline commands (replay, decode, export, report, check, diff, learn, query) need none."""
    import importlib

    missing = []
    for name in POSIX_TTY:
        try:
            importlib.import_module(name)
        except ImportError:
            missing.append(name)
    if missing:
        raise UsageError(f"{what} needs a POSIX serial-port interface ({', '.join(missing)}: Linux, macOS, BSD), "
                         f"which this Python does not have; the offline commands (replay, decode, export, report, "
                         f"check, diff, learn, query) work here")


def stream_sink(spec: CaptureSpec, line_buffered: bool):
    """The text, JSONL or pcapng stream on stdout (None with --quiet)."""
    if spec.stream == "jsonl":
        from sniffer.formats.jsonl import JsonlSink

        return JsonlSink(sys.stdout.buffer, flush=line_buffered)
    if spec.stream == "text":
        from sniffer.formats.text import TextSink

        return TextSink(sys.stdout, flush=line_buffered)
    if spec.stream == "pcapng":
        from sniffer.formats.pcap.writer import PcapSink

        return PcapSink(sys.stdout.buffer, ng=True, comments=True, flush=line_buffered)
    return None


def capture_sinks(spec: CaptureSpec, label: str, *, stream=True, inputs=(), line_buffered=True,
                  timed_flush=True) -> list:
    """A capture's sinks: the stdout stream, the MCAP file (or its segments, --rotate), viewers on a
    socket (last: the file is closed before viewers are let go).  Outputs are checked (and the socket
    bound) now, before the port opens.  `timed_flush=False` (a file decoded again): the MCAP is written as
    its writer fills it, not every second of wall time, so its bytes depend on the capture alone."""
    from sniffer.capture.status import check_status
    from sniffer.processes.publish_sink import PublishSink

    check_status(spec)  # before --rotate makes its folder
    inputs = [*inputs, *spec.read_paths()]
    sinks = []
    if stream:
        s = stream_sink(spec, line_buffered=line_buffered)
        if s is not None:
            sinks.append(s)
    ring = spec.trigger is not None and spec.trigger.ring  # --ring: only the windows
    if spec.out and spec.rotate is not None and not ring:
        from sniffer.formats.mcap.rotating import SegmentPlan

        sinks.append(SegmentPlan(spec.out, spec.rotate, spec.keep, inputs=inputs, timed_flush=timed_flush))
    elif spec.out and not ring:
        sinks.append(FileSink("mcap", spec.out, inputs=inputs, timed_flush=timed_flush))
    if spec.publish:
        sinks.append(PublishSink(spec.publish, label=label, capture_path=spec.out, backlog=spec.publish_backlog))
        say(f"publishing on {sinks[-1].address} (view: sniffer attach {sinks[-1].address})")
    return sinks


def line_warning(file: str | None = None):
    """The sink that says once on stderr when most frames are CRC errors, UART errors or noise, and what to do
    (sniffer.analysis.linehealth): `detect` on the port read now, or for a capture `file` the settings to try."""
    from sniffer.analysis.linehealth import LineWarning
    from sniffer.detect.hint import what_to_do

    return LineWarning(lambda info, link: what_to_do(info, link, file=file), say)


def destination(spec: CaptureSpec, session: Session) -> str:
    """' -> cab3.mcap (written as cab3.mcap.part until the capture ends)', or the segments' folder, or ''."""
    if not spec.out:
        return ""
    if spec.rotate is not None:
        from sniffer.formats.mcap.segments import folder_for

        keep = f", keeping {spec.keep.describe()}" if spec.keep else ""
        return (f" -> segments in {folder_for(spec.out)}/ (a new one every {spec.rotate.describe()}{keep}; "
                f"status: sniffer status {folder_for(spec.out)})")
    if not session.outputs:
        return ""  # --ring: only the trigger windows are written
    return f" -> {spec.out} (written as {session.outputs[0].part} until the capture ends)"


def report(session: Session, *, label: str = "") -> int:
    """Say how the run ended (damage, error) and give its exit code."""
    where = f"{label}: " if label else ""
    for note in session.notes:
        say(f"note: {note}")
    if session.damage:
        first = session.damage[0]
        if label and first.startswith(label):  # the reader names the file already
            where = ""
        more = f" (and {len(session.damage) - 1} more)" if len(session.damage) > 1 else ""
        say(f"error: {where}input damaged: {first}{more}; everything readable was decoded, "
            f"frames after a hole are marked source.gap")
        if session.error:
            say(f"error: {session.error}")
        return EXIT_USAGE
    if session.error:
        unchanged = ""
        if session.storage_error and not session.keep_partial and session.outputs:
            unchanged = "; nothing written (a file that was there is unchanged)"
        say(f"error: {session.error}{unchanged}")
        return EXIT_FAILED if session.storage_error else EXIT_USAGE
    return EXIT_OK


def tui_wanted(spec: CaptureSpec) -> bool:
    """The TUI is the default on a terminal; --headless, --quiet, --format jsonl or a pipe keep the stream."""
    return (not spec.headless and spec.stream == "text" and sys.stdout.isatty() and sys.stdin.isatty())
