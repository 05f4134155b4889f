"""The commands: one module each, named for its command, that declares its flags and runs it.

A command module has `add_parser(subparsers)` (its parser, built with commands/flags.py's
`command_parser` and flag groups) and `run(spec, args)` (a few lines that pick a source and sinks
and run a sniffer.capture.session.Session).  Adding a command is adding its module: `build_parser`
finds every module here that has both.  What they share:

    flags.py     the parser, value types and flag groups (a flag is declared once)
    common.py    exit codes, the stdout stream, a capture's sinks, the end-of-run report
    capture.py   a capture's session and run (live, demo; and the capture process of the TUI and serve)
    dataset.py   captures into a fleet dataset (export --to dataset, ingest)

cli.py parses the flags into a CaptureSpec and calls `run(name, spec, args)`.
"""

from __future__ import annotations

import argparse

import functools
import importlib
import pkgutil

_NOT_COMMANDS = frozenset({"pytest_plugin"})  # pytest's entry point: imports pytest
FIELD_WORKFLOW = """\
the first hour on a line:
  sniffer demo                                       # see it work on a simulated bus
  sniffer detect /dev/ttyUSB0 --write-bus line.toml  # settings unknown? listen and find them
  sniffer live /dev/ttyUSB0 --bus line.toml          # capture and decode (q, y: stop, file kept)
  sniffer replay sniffer-*.mcap --tui                # look again, at the office

`sniffer COMMAND --help` shows a command's flags and examples; `sniffer man` the whole manual."""


@functools.cache
def modules() -> dict:
    """{command name: its module}, sorted by name: every module of this package with add_parser and run."""
    found = {}
    for info in pkgutil.iter_modules(__path__):
        if info.ispkg or info.name in _NOT_COMMANDS:
            continue
        m = importlib.import_module(f"{__name__}.{info.name}")
        if callable(getattr(m, "add_parser", None)) and callable(getattr(m, "run", None)):
            found[info.name] = m
    return dict(sorted(found.items()))


class _Version(argparse.Action):
    """--version: the version and which per-frame path runs (sniffer.hot), on two lines (argparse's own
    version action rewraps its text into one)."""

    def __init__(self, option_strings, version: str, dest=argparse.SUPPRESS, help="show the version and which "
                 "per-frame path runs (compiled or pure Python), then exit") -> None:
        super().__init__(option_strings, dest=dest, default=argparse.SUPPRESS, nargs=0, help=help)
        self.version = version

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from sniffer.hot import describe

        print(f"{self.version}\n{describe()}")  # stdout, as argparse's version action writes it
        parser.exit()


def build_parser():
    """The `sniffer` parser: each command module adds its own."""
    from sniffer import __version__
    from sniffer.commands.flags import Parser, prose

    p = Parser(prog="sniffer", description=prose("Passive RS-485 sniffer for PLC <-> drive links (Modbus RTU, "
                                                 "Modbus ASCII, PD-series): it listens, never sends."),
               epilog=FIELD_WORKFLOW)
    p.add_argument("--version", action=_Version, version=f"sniffer {__version__}")
    sub = p.add_subparsers(dest="cmd", metavar="COMMAND", parser_class=Parser)
    for m in modules().values():
        m.add_parser(sub)
    return p


def run(name: str, spec, args) -> int:
    """Run command `name` with its parsed flags and their CaptureSpec."""
    return modules()[name].run(spec, args)

