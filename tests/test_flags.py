"""The command line's parts (sniffer/commands/flags.py and each command's add_parser): every command's help
ends with examples and shows every default, each help is right for its command, a flag is declared once,
and every flag that takes a time reads the same units."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from sniffer.capture.settings import CaptureSpec
from sniffer.cli import build_parser, main
from sniffer.commands import modules
from sniffer.commands.flags import SAYS_DEFAULT

PARSER = build_parser()
COMMANDS = {name: p for a in PARSER._actions if a.nargs == "A..." for name, p in a.choices.items()}


def _options(p):
    return [a for a in p._actions if a.option_strings and a.help != "==SUPPRESS==" and "--help" not in a.option_strings]


def _entry(help_text: str, action) -> str:
    """The lines --help prints for one option: from its flags to the next option or group."""
    lines = help_text.splitlines()
    first = action.option_strings[0]
    for i, line in enumerate(lines):
        if line.strip().startswith(first) and (len(line.strip()) == len(first) or line.strip()[len(first)] in " ,"):
            block = [line]
            for more in lines[i + 1:]:
                if not more.startswith(" " * 6) or more.strip().startswith("-"):
                    break
                block.append(more)
            return " ".join(x.strip() for x in block)
    raise AssertionError(f"{first} not in the help")


def test_every_command_is_a_module_with_its_parser():
    assert set(COMMANDS) == set(modules())
    assert {"live", "replay", "decode", "demo", "detect", "export", "report", "check", "diff", "learn", "query",
            "completion", "man"} <= set(COMMANDS)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_help_ends_with_two_to_four_examples_of_the_command(name):
    text = COMMANDS[name].format_help()
    head, _, examples = text.rpartition("\nexamples:\n")
    assert head, f"sniffer {name} --help has no examples"
    lines = [x for x in examples.splitlines() if x.strip()]
    assert 2 <= len(lines) <= 4 and all("sniffer " in x for x in lines), lines
    assert any(x.startswith(f"  sniffer {name}") for x in lines)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_example_parses(name):
    """An example is a command line the parser takes (what the shell would pass: up to a pipe, a redirection,
    `&&` or a comment)."""
    import shlex

    for line in COMMANDS[name].examples:
        line = line.split("  #")[0].replace("source <(", "").replace(")", " ")
        words = shlex.split(line, comments=True)
        cut = next((i for i, w in enumerate(words) if w in ("|", ">", "&&")), len(words))
        words = words[words.index("sniffer") + 1:cut]
        PARSER.parse_args(words)  # a flag it lacks, a bad value: UsageError


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_help_shows_every_default(name):
    """An option with a default says it (argparse's own, or where it comes from: --baud's is the bus file's,
    the capture's, else 9600), in the words --help prints."""
    text = COMMANDS[name].format_help()
    for a in _options(COMMANDS[name]):
        entry = _entry(text, a)
        if a.default not in (None, False, []):
            shown = f"{a.default:g}" if isinstance(a.default, float) else str(a.default)
            assert SAYS_DEFAULT.search(entry) and shown in entry, entry
        if a.dest in ("baud", "parity", "stopbits", "protocol", "timeout_ms", "device", "map_base", "duration"):
            assert SAYS_DEFAULT.search(entry), entry


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_a_help_names_only_flags_its_command_has(name):
    """`replay --help` once told --quiet as live's ("the MCAP and --publish only": replay has no --publish).
    A flag an option's help names is one of this command's, unless it is quoted as another command's."""
    p = COMMANDS[name]
    own = {s for a in p._actions for s in a.option_strings}
    text = p.format_help().rpartition("\nexamples:\n")[0]
    for a in _options(p):
        entry = re.sub(r"`[^`]*`", "", _entry(text, a))  # `sniffer attach SOCKET`, `live --bus`: another's
        entry = re.sub(r"\blive --bus\b", "", entry)
        named = set(re.findall(r"(?<![\w-])--[a-z][a-z-]*[a-z]", entry))
        assert named <= own, f"sniffer {name} {a.option_strings[0]}: names {sorted(named - own)}"


def test_quiet_says_what_each_command_still_writes():
    live, replay = (_entry(COMMANDS[c].format_help(), next(a for a in _options(COMMANDS[c]) if a.dest == "quiet"))
                    for c in ("live", "replay"))
    assert live != replay and "--publish" in live and "--publish" not in replay


# a name that means another thing in another command: each command's file (--out), output (--format), --to
# (export's format, ingest's dataset), --quiet (the frame stream; detect's progress), --tui (replay's view of a
# file; attach's without a terminal), decode's hidden --baud (its frames' timing only)
OWN_MEANINGS = {"--out", "--format", "--to", "--quiet", "--tui", "--baud"}


def test_a_flag_is_declared_once():
    """Each flag's add_argument is written once in sniffer/commands/ (a flag several commands take lives in a
    group of flags.py): --publish-backlog, --headless, --scenario ... were once written per command."""
    src = "\n".join(p.read_text() for p in Path("sniffer/commands").glob("*.py"))
    declared = re.findall(r"add_argument\(\s*(?:\"-\w\", )?\"(--[a-z-]+)\"", src)
    assert len(declared) > 80
    assert {f for f in declared if declared.count(f) > 1} <= OWN_MEANINGS


# ---------------------------------------------------------------- durations: one grammar
def _spec(*argv):
    return CaptureSpec.from_args(PARSER.parse_args(list(argv)))


def test_every_time_flag_takes_units():
    """Every flag that takes a time reads 90s, 5m, 1.5h, 1d, 300ms (the one grammar); none is a plain float."""
    timed = [(name, a) for name, p in COMMANDS.items() for a in _options(p) if a.metavar == "TIME"
             or a.dest in ("duration", "timeout_ms", "max_time", "quiet_time", "units_time", "time_tol_ms",
                           "latency_tol_ms", "pre", "post", "max_window", "on_trigger_timeout", "mqtt_interval")]
    assert len({a.dest for _, a in timed}) >= 12
    for name, a in timed:
        assert getattr(a.type, "__name__", "") == "duration", f"sniffer {name} {a.option_strings[0]}"


@pytest.mark.parametrize("argv, get, want", [
    (["live", "/dev/ttyUSB0", "--duration", "1m"], lambda s, a: s.duration_s, 60.0),
    (["live", "/dev/ttyUSB0", "--duration", "90"], lambda s, a: s.duration_s, 90.0),  # bare: seconds, as before
    (["demo", "--duration", "1.5h"], lambda s, a: s.duration_s, 5400.0),
    (["simulate", "--out", "x.mcap", "--duration", "1d"], lambda s, a: s.duration_s, 86400.0),
    (["replay", "x.mcap", "--timeout-ms", "1.5s"], lambda s, a: s.flags.timeout_ms, 1500.0),
    (["replay", "x.mcap", "--timeout-ms", "250"], lambda s, a: s.flags.timeout_ms, 250.0),  # bare: ms
    (["detect", "/dev/ttyUSB0", "--max-time", "2min"], lambda s, a: a.max_time, 120.0),
    (["detect", "/dev/ttyUSB0", "--quiet-time", "500ms"], lambda s, a: a.quiet_time, 0.5),
    (["check", "x.mcap", "--golden", "g.txt", "--time-tol-ms", "2"], lambda s, a: a.time_tol_ms, 2.0),
    (["check", "x.mcap", "--golden", "g.txt", "--latency-tol-ms", "300us"], lambda s, a: a.latency_tol_ms, 0.3),
    (["replay", "x.mcap", "--trigger", "crc", "--pre", "5m", "--post", "0"], lambda s, a: (s.trigger.pre_s,
                                                                                          s.trigger.post_s), (300, 0)),
    (["replay", "x.mcap", "--mqtt", "mqtt://h/p", "--mqtt-interval", "500ms"], lambda s, a: s.mqtt.interval_s, 0.5),
    (["live", "/dev/ttyUSB0", "--rotate", "1w", "--keep", "2d"], lambda s, a: (s.rotate.span_ns, s.keep.age_ns),
     (7 * 86400 * 10**9, 2 * 86400 * 10**9)),
    (["live", "/dev/ttyUSB0", "--rotate", "90000us"], lambda s, a: s.rotate, None),  # under a second: refused
])
def test_durations_read_one_way(argv, get, want):
    if want is None:
        with pytest.raises(Exception, match="at least 1 s"):
            _spec(*argv)
        return
    args = PARSER.parse_args(argv)
    got = get(CaptureSpec.from_args(args), args)
    assert got == pytest.approx(want)


@pytest.mark.parametrize("argv, says", [
    (["demo", "--duration", "1x"], "--duration '1x': unknown time unit 'x'"),
    (["demo", "--duration", "soon"], "--duration 'soon': not a time"),
    (["demo", "--duration", "400d"], "--duration '400d': from 0 to 366d"),
    (["replay", "x.mcap", "--timeout-ms", "-5"], "--timeout-ms '-5': from 0 to"),
    (["detect", "/dev/null", "--units-time", "2 fortnights"], "--units-time '2 fortnights': unknown time unit"),
    (["check", "x.mcap", "--golden", "g", "--time-tol-ms", "nan"], "--time-tol-ms 'nan': not a time"),
])
def test_a_bad_time_is_one_line_naming_the_flag(capsys, argv, says):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sniffer: error: ") and says in err, err
