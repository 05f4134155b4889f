"""`sniffer completion bash|zsh|fish`: the shell's completion script, generated from the parser itself (shtab).

Every command, flag and choice the parser knows completes; arguments that name a file, a
folder or a port complete as paths.  A new flag needs nothing here: the script is made from
the same parser that reads the command line.
"""

from __future__ import annotations

import argparse
import sys

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK, UsageError
from sniffer.commands.flags import command_parser

SHELLS = ("bash", "zsh", "fish")
# where each shell finds a completion script it loads by itself (the help says it; packagers install there)
PLACES = {"bash": "~/.local/share/bash-completion/completions/sniffer", "zsh": "a folder on $fpath, as _sniffer",
          "fish": "~/.config/fish/completions/sniffer.fish"}
_FILE_METAVARS = ("FILE", "PATH", "CAPTURE", "GOLDEN", "BEFORE", "AFTER", "SOCKET", "PORT")
_DIR_METAVARS = ("DIR", "FOLDER")
_FILE_DESTS = ("file", "captures", "ports", "port", "socket", "a", "b", "path", "out")
_DIR_DESTS = ("folder", "dataset", "windows")


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "completion", help="print the shell completion script for bash, zsh or fish",
        description="""\
            Print a completion script for your shell: commands, flags, their choices and file names then
            complete with Tab.  Load it once in the shell you are in, or install it where the shell finds
            it by itself: bash """ + PLACES["bash"] + """, zsh """ + PLACES["zsh"] + """, fish """
                    + PLACES["fish"] + ".",
        examples=["source <(sniffer completion bash)                  # this shell, now",
                  "sniffer completion bash > ~/.local/share/bash-completion/completions/sniffer",
                  "sniffer completion zsh > ~/.zfunc/_sniffer         # with fpath+=(~/.zfunc) in ~/.zshrc",
                  "sniffer completion fish > ~/.config/fish/completions/sniffer.fish"])
    p.add_argument("shell", choices=SHELLS, help="the shell the script is for")


def run(spec: CaptureSpec, args) -> int:
    sys.stdout.write(script(args.shell))
    return EXIT_OK


def script(shell: str) -> str:
    """The completion script of `shell` for the whole `sniffer` parser."""
    try:
        import shtab
    except ImportError:
        raise UsageError("sniffer completion needs shtab (pip install shtab)") from None
    from sniffer.commands import build_parser

    parser = build_parser()
    kinds = {"file": shtab.FILE, "dir": shtab.DIRECTORY}
    for p in parsers(parser):
        for action in p._actions:  # argparse keeps them there; shtab reads `complete` off each
            kind = path_kind(action)
            if kind is not None:
                action.complete = kinds[kind]
    text = shtab.complete(parser, shell=shell)
    return text if text.endswith("\n") else text + "\n"


def parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parser and every command's (one level: sniffer's commands have no subcommands)."""
    out = [parser]
    for action in parser._actions:
        if action.nargs == argparse.PARSER:
            out += list(dict.fromkeys(action.choices.values()))
    return out


def path_kind(action: argparse.Action) -> str | None:
    """"file", "dir" or None: what an argument names, told by its metavar or name (the flags say FILE, DIR ...)."""
    if action.nargs == 0 or action.choices is not None or action.help == argparse.SUPPRESS:
        return None
    metavar = action.metavar[0] if isinstance(action.metavar, tuple) else action.metavar
    name = (metavar or action.dest or "").upper()
    if any(name.startswith(m) for m in _DIR_METAVARS) or (metavar is None and action.dest in _DIR_DESTS):
        return "dir"
    if any(name.startswith(m) for m in _FILE_METAVARS) or (metavar is None and action.dest in _FILE_DESTS):
        return "file"
    return None
