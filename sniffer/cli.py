"""Command line: parse the flags into a CaptureSpec (sniffer.capture.settings) and run a command (sniffer.commands).

Each command module declares its own flags (sniffer/commands/*.py: add_parser, run); this
module only builds the parser from them and runs the one asked for.  Bad input gets one clear
line on stderr and exit code 2 (a capture that could not be written: 1; Ctrl-C: 130), never a
traceback.
"""

from __future__ import annotations

import os
import sys

from sniffer.commands import build_parser, run
from sniffer.commands.common import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_USAGE, UsageError
from sniffer.line import SettingsError
from sniffer.events import CaptureError

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not args.cmd:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        from sniffer.capture.settings import CaptureSpec

        if getattr(args, "spec_from_stdin", False):  # the capture process of a TUI or serve (processes/capture.py)
            spec = CaptureSpec.decode(sys.stdin.buffer.read())
        else:
            spec = CaptureSpec.from_args(args)
        return run(args.cmd, spec, args)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # output piped into `head` etc.: stop quietly
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except Exception as e:  # noqa: BLE001 - sorted below: bad input is one line, a bug keeps its traceback
        rc = _one_line(e)
        if rc is None:
            raise
        return rc


def _one_line(e: Exception) -> int | None:
    """Print `e` as one error line and give its exit code, or None for an error that is a bug."""
    from decoders.registry import DeviceMapError
    from decoders.tables import MapError

    from sniffer import MissingExtra
    from sniffer.capture.busfile import BusFileError
    from sniffer.simulator.faults import FaultError
    from sniffer.simulator.overrides import OverrideError
    from sniffer.formats.mcap.sink import CaptureStorageError

    if isinstance(e, (UsageError, CaptureError, SettingsError, DeviceMapError, BusFileError, MapError,
                      OverrideError, FaultError, MissingExtra)):
        _say(str(e))
        return EXIT_USAGE
    if isinstance(e, CaptureStorageError):
        _say(str(e))
        return EXIT_FAILED
    from sniffer.parallel.engine import WorkerError

    if isinstance(e, WorkerError):  # a part's process failed: its last line (the traceback is on stderr above)
        _say(f"--jobs: {str(e).strip().splitlines()[0]}")
        return EXIT_FAILED
    if isinstance(e, OSError):  # e.g. an output that cannot be written
        _say(f"{e.filename + ': ' if isinstance(e.filename, str) else ''}{e.strerror or e}")
        return EXIT_FAILED
    return None


def _say(text: str) -> None:
    text = " ".join(text.split())  # one line, whatever the message held
    if len(text) > 400:
        text = text[:397] + "..."
    print(f"sniffer: error: {text}", file=sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
