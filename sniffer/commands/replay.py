"""`sniffer replay FILE` (a capture file, decoded again) and `sniffer decode HEX...` (frames typed in)."""

from __future__ import annotations

import sys

from sniffer.events import CaptureInfo, Chunk
from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import UsageError, jobs_for, report, say, stream_sink


def file_source(spec: CaptureSpec):
    """The capture of a replay-like command: one file (a killed capture's part file when only that is
    there), or a set read as one capture: several files, a rotated capture's folder or its index."""
    from sniffer.formats.outputs import readable
    from sniffer.sources.segset import capture_source, is_set

    if is_set(spec.inputs or spec.input):
        return capture_source(spec.inputs, spec.input_format)
    path, note = readable(spec.input)
    if note:
        say(f"note: {note}")
    return capture_source(path, spec.input_format, spec.logic)


def cmd_replay(spec: CaptureSpec, args) -> int:
    if (spec.rotate is None) != (args.out is None):
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
    if jobs > 1:
        return _parallel(spec, source, args, jobs)
    bar = None
    session = Session(spec, source, [s for s in (stream_sink(spec, line_buffered=False),) if s is not None])
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
    """replay --jobs N: the capture decoded by parts in N processes (sniffer.parallel), the same lines."""
    from sniffer.commands.common import parallel_run, run_with_bar
    from sniffer.parallel.outputs import StreamPlan, StreamWriter, stdout_for

    outputs = [(StreamPlan(spec.stream), StreamWriter(stdout_for(spec.stream)))] \
        if spec.stream in ("text", "jsonl") else []
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

    sinks = capture_sinks(spec, spec.input, inputs=spec.inputs or [spec.input], line_buffered=False)
    session = Session(spec, source, sinks, label=f"replay {spec.input}")
    session.open()
    say(f"replaying {spec.input}{destination(spec, session)}")
    session.run()
    note_unfinished(session)
    print(summary_line(session), file=sys.stderr)
    return report(session, label=spec.input)


def note_unfinished(session: Session) -> None:
    paths = list(getattr(session.source, "unfinished", None) or ())
    if not paths and session.info.extra.get("mcap_unfinished"):
        paths = [session.spec.input]
    for path in paths:
        say(f"note: {path} was not closed cleanly (capture killed, or still being written?); read up to its last "
            f"complete record. 'sniffer repair {path}' writes a clean copy.")


class HexSource:
    """Frames typed in, each one burst on the line with silence between.

    The input has no time: the capture says time source "none", so nothing reports a
    latency, a timeout or a short silence (the times only keep the frames apart: a gap longer
    than any protocol's quiet time, PD's 50 ms included).
    """

    GAP_NS = 100_000_000

    def __init__(self, frames: list[bytes], spec: CaptureSpec) -> None:
        self.frames = frames
        self.line = spec.resolve(None, need_baud=False).line

    def open(self) -> CaptureInfo:
        line = self.line
        return CaptureInfo(source="decode", baud=line.baud, parity=line.parity, stopbits=line.stopbits,
                           time_source="none")

    def events(self):
        line = self.line
        t = 0
        gap = max(10 * line.t35_ns, self.GAP_NS)
        for data in self.frames:
            times = tuple(t + i * line.char_ns for i in range(len(data)))
            yield Chunk(t, data, times)
            t = times[-1] + line.char_ns + gap


_HEX_DIGITS = frozenset("0123456789abcdefABCDEF")


def _hex_bytes(arg: str) -> bytes | None:
    """The bytes an argument of hex digits (spaces allowed) writes, or None if it is not one."""
    t = arg.replace(" ", "")
    if not t or len(t) % 2 or not set(t) <= _HEX_DIGITS:
        return None
    return bytes.fromhex(t)


def text_frame(arg: str) -> bytes:
    """One argument of `decode` in a text (ASCII) protocol, as the characters on the wire.

    * ':0103...' is the frame's characters (CR LF added if missing);
    * hex digits without ':' are bytes: the wire characters in hex when they are printable
      characters holding a ':' (3A3031...0D0A; several frames and junk as they were sent),
      else the frame's binary content (unit, function, data, LRC), sent as ':' + its hex +
      CR LF (so '010300000001FB' and ':010300000001FB' agree).
    Anything else is a usage error (never decoded as garbage).
    """
    t = arg.strip()
    if t.startswith(":"):
        data = t.encode("ascii", "replace")
        return data if data.endswith(b"\r\n") else data + b"\r\n"
    b = _hex_bytes(t)
    if b is None:
        raise UsageError(f"not a frame: {arg[:60]!r} (give ':' and the frame's characters, or its bytes in hex)")
    if b":" in b and all(0x20 <= c < 0x7F or c in b"\r\n" for c in b):
        # the wire characters in hex: one frame or several, junk included, as they were sent
        return b if b.endswith(b"\r\n") or b.count(b":") > 1 else b + b"\r\n"
    return b":" + b.hex().upper().encode() + b"\r\n"


def cmd_decode(spec: CaptureSpec, args) -> int:
    text = spec.resolve(None, need_baud=False).protocol.text
    frames = []
    for h in args.hex:
        if text:
            data = text_frame(h)
        else:
            t = h.replace(" ", "").replace(":", "")
            try:
                data = bytes.fromhex(t)
            except ValueError:
                raise UsageError(f"not hex: {h[:60]!r}") from None
        if data:
            frames.append(data)
    session = Session(spec, HexSource(frames, spec), [stream_sink(spec, line_buffered=False)], need_baud=False)
    session.run()
    return report(session)
