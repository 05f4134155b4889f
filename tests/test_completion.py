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


# ------------------------------------------------- values the parser checks later, and "did you mean"
def _complete_words(bash_script, line: str, words: list[str]) -> list[str]:
    """As _complete, with COMP_WORDS as bash cuts them (at '=' too: COMP_WORDBREAKS)."""
    prog = f"""
source {bash_script}
fn=$(sed -E 's/.* -F ([^ ]+) .*/\\1/' <<<"$(complete -p sniffer)")
COMP_LINE={line!r}; COMP_POINT=${{#COMP_LINE}}
COMP_WORDS=({" ".join(repr(w) for w in words)}); COMP_CWORD={len(words) - 1}
"$fn" sniffer {words[-1]!r} {words[-2]!r}
printf '%s\\n' "${{COMPREPLY[@]}}"
"""
    r = subprocess.run(["bash", "--norc", "--noprofile", "-c", prog], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout.split()


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash here")
def test_bash_completes_scenarios_faults_formats_and_models(bash_script):
    from decoders.registry import builtin_decoders
    from sniffer.simulator.faults import KINDS

    assert _complete(bash_script, "sniffer demo --scenario a5") == ["a510", "a510-ascii"]
    assert _complete(bash_script, "sniffer simulate --scenario pd") == ["pd-series", "pd-series-ascii"]
    assert _complete(bash_script, "sniffer demo --fault unit_s") == ["unit_silent"]
    assert sorted(_complete(bash_script, "sniffer demo --fault unit")) == ["unit_refuses", "unit_silent"]
    assert set(_complete(bash_script, "sniffer demo --fault ")) == set(KINDS)
    assert _complete(bash_script, "sniffer export x.mcap --to pc") == ["pcap", "pcapng"]
    assert "dataset" in _complete(bash_script, "sniffer export x.mcap --to ")
    # --device UNIT=MODEL: the word as bash keeps it without '=' splitting, and as it cuts it at '='
    assert _complete(bash_script, "sniffer replay x.mcap --device 1=a5") == ["1=a510", "1=a510-hf"]
    line = "sniffer replay x.mcap --device 1=a5"
    assert _complete_words(bash_script, line, ["sniffer", "replay", "x.mcap", "--device", "1", "=", "a5"]) == \
        ["a510", "a510-hf"]
    line = "sniffer live --device 12="
    assert set(_complete_words(bash_script, line, ["sniffer", "live", "--device", "12", "="])) == \
        set(builtin_decoders())
    assert set(_complete(bash_script, "sniffer replay x.mcap --device 3")) == {f"3={m}" for m in builtin_decoders()}
    # the words after a UNIT=MODEL are read as before: flags, and their values
    line = "sniffer replay x.mcap --device 2=tds-v8 --parity "
    assert _complete_words(bash_script, line, ["sniffer", "replay", "x.mcap", "--device", "2", "=", "tds-v8",
                                               "--parity", ""]) == ["N", "E", "O"]


@pytest.mark.parametrize("shell", ["zsh", "fish"])
def test_zsh_and_fish_complete_models_after_the_unit(shell):
    text = script(shell)
    assert "_sniffer_device" in text and "a510-hf" in text and "unit_silent" in text and "pd-series-ascii" in text


@pytest.mark.parametrize("argv,said", [
    (["dignose", "x.mcap"], "invalid choice: 'dignose'"),
    (["replay", "x.mcap", "--quite"], "unrecognized arguments: --quite; did you mean '--quiet'?"),
    (["replay", "x.mcap", "--bsud=9600"], "did you mean '--baud'?"),
    (["replay", "{a510}", "--quiet", "--device", "1=tdsv8"], "unknown model 'tdsv8' for unit 1"),
    (["decode", "0103", "--protocol", "modbus-rt"], "did you mean 'modbus-rtu'?"),
    (["simulate", "--scenario", "defualt", "--out", "{out}"], "unknown scenario 'defualt'"),
    (["simulate", "--fault", "unit_slient:2", "--out", "{out}"], "--fault 'unit_slient:2': unknown kind"),
])
def test_a_mistyped_name_gets_the_closest_one_in_one_line_exit_2(argv, said, tmp_path, capsys):
    from pathlib import Path

    a510 = Path(__file__).resolve().parents[1] / "captures" / "sim" / "a510.mcap"
    out = tmp_path / "out.mcap"
    assert main([a.format(a510=a510, out=out) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and said in err, err
    want = {"dignose": "diagnose", "tdsv8": "tds-v8", "defualt": "default", "unit_slient:2": "unit_silent"}
    for typo, right in want.items():
        if typo in argv:
            assert err.rstrip().endswith(f"did you mean '{right}'?"), err
    assert not out.exists()


def test_no_suggestion_when_nothing_is_close(capsys):
    from sniffer.stderr import did_you_mean

    assert did_you_mean("a150", ["a510", "tds-v8"]) == "; did you mean 'a510'?"
    assert did_you_mean("A510", ["a510"]) == "; did you mean 'a510'?"
    assert did_you_mean("zzzz", ["a510", "tds-v8"]) == ""
    assert main(["decode", "0103", "--protocol", "xyz"]) == 2
    assert "did you mean" not in capsys.readouterr().err
