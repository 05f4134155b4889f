"""`sniffer attach SOCKET`: a viewer of a capture that another process publishes (--publish, sniffer serve)."""

from __future__ import annotations

import argparse

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import tui_wanted
from sniffer.commands.flags import command_parser, headless_flag, stream_flags


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "attach", help="view a capture that another process publishes (--publish, sniffer serve)",
        description="""\
            View a running capture from another terminal or another machine: the TUI (or frame lines,
            --headless) of what `sniffer live ... --publish SOCKET` or `sniffer serve` captures.  A viewer
            only reads: it cannot stop the capture nor delay its reads; any number may attach.""",
        examples=["sniffer attach /tmp/cab3.sock",
                  "sniffer attach tcp:10.0.0.5:7485 --headless --format jsonl"])
    p.add_argument("socket", help="the capture's socket (or tcp:[HOST:]PORT)")
    headless_flag(p)
    p.add_argument("--tui", action="store_true", help="the TUI even without a terminal (sniffer serve uses it)")
    p.add_argument("--exit-with-parent", action="store_true", help=argparse.SUPPRESS)  # serve's viewers
    stream_flags(p)


def run(spec: CaptureSpec, args) -> int:
    from sniffer.processes.attach import Attachment, run_headless
    from sniffer.tui.run import attach_tui

    if getattr(args, "exit_with_parent", False):  # a browser's viewer under `sniffer serve`
        import signal

        from sniffer.processes.parent_death import die_with_parent

        die_with_parent(signal.SIGKILL)
    att = Attachment(args.socket)  # no capture there: CaptureError, one line, exit 2
    if args.tui or tui_wanted(spec):
        return attach_tui(att)
    return run_headless(att, spec.stream or "text")
