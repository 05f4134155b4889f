"""`sniffer man`: the manual page (roff, section 1), generated from the parser itself.

One page for the tool: what it is, the first hour on a line, then every command with its
synopsis, description, options by group (each default shown, as in --help) and examples.
`sniffer man | man -l -` reads it; a packager installs it as sniffer.1.
"""

from __future__ import annotations

import argparse
import sys

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK
from sniffer.commands.flags import command_parser, help_text


def add_parser(subparsers) -> None:
    command_parser(
        subparsers, "man", help="print the manual page (roff): every command, its options and examples",
        description="""\
            Print sniffer's manual page: every command with its options (and their defaults) and examples,
            made from the same parser as --help.  Read it with `man -l`, or install it where man finds it.""",
        examples=["sniffer man | man -l -",
                  "sniffer man > ~/.local/share/man/man1/sniffer.1     # then: man sniffer"])


def run(spec: CaptureSpec, args) -> int:
    from sniffer.commands import build_parser

    sys.stdout.write(page(build_parser()))
    return EXIT_OK


def roff(text: str) -> str:
    """Text for a roff line: backslashes and hyphens escaped, a leading dot or quote made literal."""
    text = text.replace("\\", "\\e").replace("-", "\\-")
    return "\\&" + text if text[:1] in (".", "'") else text


def _lines(text: str) -> list[str]:
    return [roff(x) if x.strip() else "" for x in text.splitlines()]


def _paragraphs(text: str) -> list[str]:
    """Prose paragraphs as .PP blocks; a block of indented lines (a list, commands) kept as it is (.nf)."""
    out: list[str] = []
    for para in text.strip("\n").split("\n\n"):
        lines = para.splitlines()
        if any(x.startswith("  ") for x in lines):
            out += [".PP", ".nf", *_lines(para), ".fi"]
        else:
            out += [".PP", roff(" ".join(x.strip() for x in lines))]
    return out


def _option(action: argparse.Action, parser: argparse.ArgumentParser) -> list[str]:
    if action.option_strings:
        names = ", ".join(f"\\fB{roff(o)}\\fR" for o in action.option_strings)
        if action.nargs != 0:
            metavar = action.metavar or (("{" + ",".join(map(str, action.choices)) + "}") if action.choices else
                                         action.dest.upper())
            metavar = " ".join(metavar) if isinstance(metavar, tuple) else metavar
            names += f" \\fI{roff(metavar)}\\fR"
    else:
        names = f"\\fI{roff(action.metavar or action.dest)}\\fR"
    return [".TP", names, roff(help_text(action, parser.prog))]


def groups(parser: argparse.ArgumentParser) -> list[tuple[str, list[argparse.Action]]]:
    """(title, actions) of each group of `parser` that shows in --help (argparse keeps them on the parser)."""
    out = []
    for g in parser._action_groups:
        shown = [a for a in g._group_actions if a.help != argparse.SUPPRESS and a.nargs != argparse.PARSER
                 and "--help" not in a.option_strings]
        if shown:
            out.append((g.title, shown))
    return out


def commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if action.nargs == argparse.PARSER:
            return dict(action.choices)
    return {}


def page(parser: argparse.ArgumentParser) -> str:
    from sniffer import __version__

    cmds = commands(parser)
    out = [f'.TH SNIFFER 1 "" "sniffer {__version__}" "User Commands"', ".SH NAME",
           "sniffer \\- passive RS\\-485 sniffer for PLC and drive links (it listens, never sends)",
           ".SH SYNOPSIS", ".B sniffer", ".I COMMAND", "[\\fIOPTIONS\\fR] [\\fIARGUMENTS\\fR]", ".br",
           ".B sniffer", ".I COMMAND", "\\fB\\-\\-help\\fR", ".SH DESCRIPTION"]
    out += _paragraphs(parser.description or "")
    out += _paragraphs(parser.epilog or "")
    out += [".SH COMMANDS"]
    for name in cmds:
        out += [".TP", f"\\fB{roff(name)}\\fR", roff(getattr(cmds[name], "summary", ""))]
    for name, sub in cmds.items():
        usage = sub.format_usage().strip().splitlines()  # "usage: " gone, its continuation lines moved left as far
        usage = [usage[0].replace("usage: ", "", 1)] + [x[len("usage: "):] for x in usage[1:]]
        out += [f'.SH "SNIFFER {name.upper()}"', ".nf", *_lines("\n".join(usage)), ".fi"]
        out += _paragraphs(sub.description or "")
        for title, actions in groups(sub):
            out += [f".SS {roff(title[:1].upper() + title[1:])}"]
            for a in actions:
                out += _option(a, sub)
        epilog = (sub.epilog or "").split("examples:\n")
        if epilog[0].strip():
            out += _paragraphs(epilog[0])
        if getattr(sub, "examples", None):
            out += [".SS Examples", ".RS", ".nf", *_lines("\n".join(sub.examples)), ".fi", ".RE"]
    out += [".SH EXIT STATUS", "0 done; 1 a capture or output that could not be written (check, diff, detect: "
            "a difference, nothing settled); 2 bad flags or input (one line on stderr); 130 Ctrl\\-C.",
            ".SH SEE ALSO", "The docs folder of the source: README.md, docs/troubleshooting.md, docs/*.md."]
    return "\n".join(out) + "\n"
