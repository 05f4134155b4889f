"""What `live` and `demo` share: a capture's session (stream, MCAP, viewers' socket) and its run to the end.

Whatever ends the capture (Ctrl-C, SIGTERM, --duration, the TUI's quit, a full
disk, the source failing) the pipeline is flushed and the MCAP closed and kept.
With the TUI the capture is a process of its own and the TUI a viewer of it
(tui/run.py run_capture_tui): the UI never shares the reader's interpreter.
That process gets its CaptureSpec whole on stdin (--spec-from-stdin, hidden):
the flags are parsed once, by the command the user typed.
"""

from __future__ import annotations

import sys

from sniffer.capture.session import Session, on_signals
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import capture_sinks, destination, line_warning, report, say, summary_line


def capture_session(spec: CaptureSpec, source, label: str, *, inputs=(), status_label: str = "") -> Session:
    """The session of a capture: the stdout stream, the MCAP file, the viewers' socket; its files are kept
    whatever ends it.  Outputs are checked now; nothing is opened yet."""
    from sniffer.analysis.quietline import QuietLine

    sinks = [line_warning(), QuietLine(say), *capture_sinks(spec, label, stream=True, inputs=inputs)]
    return Session(spec, source, sinks, keep_partial=True, need_baud=False, label=status_label or label)


def run_capture(spec: CaptureSpec, source, label: str, inputs=(), what=None, status_label="") -> int:
    """Run a capture to its end (signals stop it), saying what it captures and how it ended."""
    session = capture_session(spec, source, label, inputs=inputs, status_label=status_label)
    on_signals(session.stop)
    if spec.wait_port and inputs:  # a live capture's inputs are its ports: of every link, both of a --tap
        from sniffer.capture.status import wait_for_ports

        if not wait_for_ports(list(inputs), session.stop, session.status_path(), status_label or label):
            return report(session)  # stopped while waiting: nothing captured, nothing to say
    session.open()  # a missing port, a bad setting: one line, and nothing created
    links = getattr(session.pipeline, "resolved", None)
    at = ("; ".join(f"{name} at {r.describe()}" for name, r in links.items()) if links
          else f"at {session.resolved.describe()}")
    say(f"{what() if what else 'capturing ' + label} {at} (read-only){destination(spec, session)}")
    session.run()
    print(summary_line(session), file=sys.stderr)
    return report(session)
