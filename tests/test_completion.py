"""`sniffer completion bash|zsh|fish` and `sniffer man` (sniffer/commands/completion.py, man.py): made from the
parser itself, so every command and flag is in them; the bash script loads and completes, the page renders."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest

from sniffer.cli import build_parser, main
from sniffer.commands import modules
from sniffer.commands.completion import script
from sniffer.commands.man import page

COMMANDS = sorted(modules())


@pytest.fixture(scope="module")
def bash_script(tmp_path_factory):
    path = tmp_path_factory.mktemp("completion") / "sniffer.bash"
    path.write_text(script("bash"))
    return path


def _complete(bash_script, line: str) -> list[str]:
    """What bash offers for the last word of `line` (the loaded script's function, as Tab runs it)."""
    words = line.split(" ")
    prog = f"""
source {bash_script}
spec=$(complete -p sniffer) || exit 3
fn=$(sed -E 's/.* -F ([^ ]+) .*/\\1/' <<<"$spec")
COMP_LINE={line!r}; COMP_POINT=${{#COMP_LINE}}
COMP_WORDS=({" ".join(repr(w) for w in words)}); COMP_CWORD={len(words) - 1}
"$fn" sniffer {words[-1]!r} {words[-2]!r}
printf '%s\\n' "${{COMPREPLY[@]}}"
"""
    r = subprocess.run(["bash", "--norc", "--noprofile", "-c", prog], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout.split()


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash here")
def test_bash_completes_commands_flags_and_choices(bash_script):
    assert _complete(bash_script, "sniffer re") == ["repair", "replay", "report"]
    assert set(_complete(bash_script, "sniffer ")) >= set(COMMANDS)
    assert _complete(bash_script, "sniffer live --ba") == ["--baud"]
    assert "--publish-backlog" in _complete(bash_script, "sniffer serve --pub")
    assert _complete(bash_script, "sniffer live --parity ") == ["N", "E", "O"]
    assert _complete(bash_script, "sniffer completion ") == ["bash", "zsh", "fish"]
    assert "--spec-from-stdin" not in _complete(bash_script, "sniffer live --")  # the capture process's own


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash here")
def test_bash_completes_file_arguments_as_paths(bash_script, tmp_path, monkeypatch):
    (tmp_path / "cab3.mcap").write_text("")
    monkeypatch.chdir(tmp_path)
    assert "cab3.mcap" in _complete(bash_script, "sniffer replay cab")
    assert "cab3.mcap" in _complete(bash_script, "sniffer live --bus cab")


@pytest.mark.parametrize("shell", ["zsh", "fish"])
def test_zsh_and_fish_scripts_name_every_command_and_flag(shell):
    text = script(shell)
    assert text.strip()
    for name in COMMANDS:
        assert name in text
    for flag in ("baud", "publish-backlog", "mqtt-interval", "write-bus", "update-golden"):
        assert flag in text
    if shutil.which(shell):  # the shell itself reads it without a syntax error
        check = ["zsh", "-n"] if shell == "zsh" else ["fish", "--no-execute"]
        r = subprocess.run([*check, "/dev/stdin"], input=text, capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr


def test_completion_prints_the_script(capsys):
    assert main(["completion", "bash"]) == 0
    assert "complete" in capsys.readouterr().out
    assert main(["completion", "tcsh"]) == 2
    assert "invalid choice" in capsys.readouterr().err


# ---------------------------------------------------------------- the man page
@pytest.fixture(scope="module")
def manpage():
    return page(build_parser())


def test_the_page_has_every_command_its_options_and_examples(manpage):
    assert manpage.startswith(".TH SNIFFER 1 ")
    for section in ("NAME", "SYNOPSIS", "DESCRIPTION", "COMMANDS", "EXIT STATUS"):
        assert f"\n.SH {section}\n" in manpage
    for name in COMMANDS:
        assert f'\n.SH "SNIFFER {name.upper()}"\n' in manpage
    assert "\\fB\\-\\-publish\\-backlog\\fR" in manpage and "(default: 100000)" in manpage
    assert manpage.count(".SS Examples") == len(COMMANDS)
    body = [x for x in manpage.splitlines() if x and not x.startswith(".")]
    assert not [x for x in body if x.startswith("'")]  # a line a roff reader would take as a request


@pytest.mark.skipif(shutil.which("groff") is None and shutil.which("man") is None, reason="no roff renderer here")
def test_the_page_renders(manpage, tmp_path):
    path = tmp_path / "sniffer.1"
    path.write_text(manpage)
    if shutil.which("groff"):
        r = subprocess.run(["groff", "-man", "-Tutf8", "-ww", "-z", str(path)], capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 0 and not r.stderr.strip(), r.stderr  # no warning: every request is known
    if shutil.which("man"):
        r = subprocess.run(["man", "-l", str(path)], capture_output=True, text=True, timeout=120,
                           env={**os.environ, "MANPAGER": "cat", "PAGER": "cat", "MANWIDTH": "100"})
        assert r.returncode == 0, r.stderr
        assert "SNIFFER LIVE" in r.stdout and "--publish-backlog" in r.stdout.replace("‐", "-")


def test_man_prints_the_page():
    assert subprocess.run([sys.executable, "-m", "sniffer", "man"], capture_output=True, text=True,
                          timeout=120).stdout.startswith(".TH SNIFFER 1")
