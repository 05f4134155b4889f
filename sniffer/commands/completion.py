"""`sniffer completion bash|zsh|fish`: the shell's completion script, generated from the parser itself (shtab).

Every command, flag and choice the parser knows completes; arguments that name a file, a
folder or a port complete as paths.  A new flag needs nothing here: the script is made from
the same parser that reads the command line.  Values the parser checks later, not as choices,
complete from their own tables (`VALUES`): --scenario's scenarios, --fault's kinds, --to's
formats, and --device UNIT=MODEL the models installed now (plugins' included: run the command
again after installing one).
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
    values = {dest: make() for dest, make in VALUES.items()}
    device = device_complete(model_names())
    for p in parsers(parser):
        for action in p._actions:  # argparse keeps them there; shtab reads `complete` off each
            if action.dest in values and action.option_strings:
                action.choices = values[action.dest]  # this parser only writes the script
                continue
            if action.dest == "device":
                action.complete = device
                continue
            kind = path_kind(action)
            if kind is not None:
                action.complete = kinds[kind]
    text = shtab.complete(parser, shell=shell)
    if shell == "bash":  # bash splits `1=a5` at '=' (COMP_WORDBREAKS): join it back before shtab reads the words
        text = text.replace(_BASH_MAIN, f"{_BASH_MAIN}\n  _sniffer_join_unit_words", 1)
    return text if text.endswith("\n") else text + "\n"


def _scenarios() -> tuple[str, ...]:
    from sniffer.commands.flags import SCENARIO_NAMES

    return SCENARIO_NAMES


def _faults() -> tuple[str, ...]:
    from sniffer.simulator.faults import KINDS

    return tuple(KINDS)


def _formats() -> tuple[str, ...]:
    from sniffer.formats import EXPORT_FORMATS

    return (*EXPORT_FORMATS, "dataset")


# a flag's dest -> its values, for flags whose values are checked after parsing (so they are not choices)
VALUES = {"scenario": _scenarios, "fault": _faults, "to": _formats}


def model_names() -> list[str]:
    """--device's models: the shipped ones and the installed plugins'."""
    from decoders.registry import builtin_decoders, plugin_decoders

    return [*builtin_decoders(), *plugin_decoders()]


_BASH_MAIN = 'local completing_word="${COMP_WORDS[COMP_CWORD]}"'
_BASH_JOIN = """
# bash cuts "--device 1=a5" into 1 = a5 (COMP_WORDBREAKS has '='): join a unit number, '=' and the model again,
# and remember it, so the model's completion answers the part after '=' as bash expects
_sniffer_join_unit_words() {
  _sniffer_split=0
  local -a words=(); local i w cword=$COMP_CWORD
  for ((i = 0; i < ${#COMP_WORDS[@]}; i++)); do
    w="${COMP_WORDS[i]}"
    if [[ "$w" == "=" && ${#words[@]} -gt 0 && "${words[-1]}" =~ ^[0-9]+$ ]]; then
      words[-1]+="="; (( i <= COMP_CWORD )) && { (( cword-- )); _sniffer_split=1; }
      if (( i + 1 < ${#COMP_WORDS[@]} )) && [[ "${COMP_WORDS[i+1]}" != -* ]]; then
        (( i++ )); words[-1]+="${COMP_WORDS[i]}"; (( i <= COMP_CWORD )) && (( cword-- ))
      fi
      continue
    fi
    words+=("$w")
  done
  (( cword < COMP_CWORD )) || _sniffer_split=0
  COMP_WORDS=("${words[@]}"); COMP_CWORD=$cword
  completing_word="${COMP_WORDS[COMP_CWORD]}"
}
"""


def device_complete(models: list[str]) -> dict:
    """shtab's completion of --device UNIT=MODEL in each shell: after a unit number and '=', the model names."""
    words = " ".join(models)
    return {
        "bash": "_sniffer_device",
        "zsh": "_sniffer_device",
        "fish": "(__sniffer_device)",
        "preamble": {
            "bash": _BASH_JOIN + f"""
_sniffer_device() {{
  local word="$1" models="{words}"
  [[ "$word" == *=* ]] || {{ [[ "$word" =~ ^[0-9]+$ ]] && compgen -W "$models" -P "$word="; return; }}
  if [[ "$_sniffer_split" == 1 ]]; then compgen -W "$models" -- "${{word#*=}}"
  else compgen -W "$models" -P "${{word%%=*}}=" -- "${{word#*=}}"; fi
}}
""",
            "zsh": f"""
_sniffer_device() {{
  if compset -P '[0-9]##='; then compadd -- {words}; else _message 'UNIT=MODEL'; fi
}}
""",
            "fish": f"""
function __sniffer_device
  set -l unit (string match -r '^[0-9]+' -- (commandline -ct))
  test -n "$unit"; or return
  for m in {words}
    echo "$unit=$m"
  end
end
""",
        },
    }


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
