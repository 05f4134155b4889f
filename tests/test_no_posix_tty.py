"""Where fcntl, termios, resource and pty do not exist (Windows, some containers) the offline commands work,
and the commands that need a serial port or a pseudo-terminal say so in one line (exit 2).

Each command runs in a Python whose sys.modules holds None for those modules before sniffer is imported
(an import of one then fails as it would there).  The TUI on a file runs under Textual's headless driver:
on Windows Textual brings a driver of its own; what is tested is that no module of ours needs them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # a Python process per command

BLOCKED = ("fcntl", "termios", "resource", "pty")
BOOT = f"import sys\nfor _m in {BLOCKED!r}:\n    sys.modules[_m] = None\n"
CLI = BOOT + "from sniffer.cli import main\nsys.exit(main(sys.argv[1:]))\n"
HERE = Path(__file__).resolve().parent.parent
A510 = str(HERE / "captures" / "sim" / "a510.mcap")
ERRORS = str(HERE / "captures" / "sim" / "errors.mcap")


def _run(code: str, *args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=300, env={**os.environ, "TEXTUAL_DRIVER": "textual.drivers.headless_driver:"
                                                                             "HeadlessDriver"})


def sniffer(*args, cwd) -> subprocess.CompletedProcess:
    return _run(CLI, *args, cwd=cwd)


def test_the_modules_are_blocked(tmp_path):
    r = _run(BOOT + "import termios\n", cwd=tmp_path)
    assert r.returncode != 0 and "termios" in r.stderr


def test_the_offline_commands_work(tmp_path):
    steps = [
        (["replay", A510, "--format", "jsonl"], 0, lambda: True),
        (["decode", "010300000002C40B"], 0, lambda: True),
        (["export", A510, "--to", "csv", "--out", "a.csv"], 0, lambda: (tmp_path / "a.points.csv").exists()),
        (["export", A510, ERRORS, "--to", "dataset", "fleet"], 0, lambda: (tmp_path / "fleet").is_dir()),
        (["query", "fleet", "--preset", "units", "--format", "csv"], 0, lambda: True),
        (["report", A510, "--out", "r.html"], 0, lambda: (tmp_path / "r.html").exists()),
        (["check", A510, "--golden", "g.txt", "--update-golden"], 0, lambda: (tmp_path / "g.txt").exists()),
        (["check", A510, "--golden", "g.txt"], 0, lambda: True),
        (["diff", A510, ERRORS], 1, lambda: True),  # 1: they differ
        (["learn", A510, "--out", "m.toml"], 0, lambda: (tmp_path / "m.toml").exists()),
        (["replay", A510, "--quiet", "--rotate", "10s", "--out", "segments"], 0,
         lambda: any((tmp_path / "segments").glob("*.mcap"))),
        (["simulate", "--out", "s.mcap", "--duration", "2"], 0, lambda: (tmp_path / "s.mcap").exists()),
        (["status", "segments"], 1, lambda: True),  # 1: the capture has ended
        (["completion", "bash"], 0, lambda: True),
        (["man"], 0, lambda: True),
    ]
    for args, rc, made in steps:
        r = sniffer(*args, cwd=tmp_path)
        assert r.returncode == rc and "Traceback" not in r.stderr, (args, r.stderr[-2000:])
        assert made(), args
        if "--quiet" not in args and args[0] in ("replay", "decode", "query", "diff", "completion", "man"):
            assert r.stdout.strip(), args


@pytest.mark.parametrize("args, needs", [
    (["live", "/dev/ttyUSB0", "--headless"], "live (reading a serial port)"),
    (["detect", "/dev/ttyUSB0"], "detect (listening on a serial port)"),
    (["simulate", "--pty", "line1"], "simulate --pty (a pseudo-terminal)"),
    (["demo", "--headless"], "demo (a simulated bus on a pseudo-terminal)"),
])
def test_what_needs_a_port_says_so_in_one_line(tmp_path, args, needs):
    r = sniffer(*args, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"sniffer: error: {needs} needs a POSIX serial-port interface")
    assert not list(tmp_path.iterdir())  # nothing made


TUI = BOOT + """
import asyncio
from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.replay import file_source
from sniffer.tui.run import session_app
from sniffer.tui.sink import TuiSink

path = sys.argv[1]
spec = CaptureSpec(input=path, inputs=(path,))
sink = TuiSink()
session = Session(spec, file_source(spec), [sink])
session.open()
app = session_app(session, sink, source_label=path, source_path=path)  # what `replay FILE --tui` runs


async def browse():
    async with app.run_test(size=(120, 40)) as pilot:
        for _ in range(300):
            await pilot.pause(0.1)
            if sink.frames_in >= int(sys.argv[2]):
                break
        for key in ("end", "home", "enter", "escape", "slash", "c", "r", "c", "enter"):  # a filter typed: crc
            await pilot.press(key)
        await pilot.pause(0.3)
        print(sink.frames_in)


asyncio.run(browse())
"""


def test_the_tui_on_a_file_runs(tmp_path):
    r = _run(TUI, A510, 500, cwd=tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert int(r.stdout.split()[-1]) >= 500  # every frame of the capture came in


# The live path as on Windows: besides the modules above, pyserial's POSIX backend (serial.serialposix, which
# `import serial` loads here and serialwin32 replaces there) is a stand-in that fails if anything opens a local
# port through it; os.fork is gone and multiprocessing starts by spawn, as on Windows.
WINDOWS_LIKE = BOOT + """
import multiprocessing, os, types
_posix = types.ModuleType("serial.serialposix")
class _NoLocalPort:
    def __init__(self, *a, **k):
        raise OSError("pyserial's POSIX backend was used")
_posix.Serial = _posix.PosixPollSerial = _posix.VTIMESerial = _NoLocalPort
sys.modules["serial.serialposix"] = _posix
for _f in ("fork", "forkpty", "fork_exec"):
    if hasattr(os, _f):
        delattr(os, _f)
multiprocessing.set_start_method("spawn", force=True)
from sniffer.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_a_gateway_line_captures_live(tmp_path):
    import json

    from gateway import Gateway
    from helpers import SimulatedLine

    from sniffer.formats.mcap.reader import open_mcap
    from sniffer.line import LineSettings

    with SimulatedLine(tmp_path, "default", "19200 8E1") as line, Gateway(line.path, LineSettings(19200, "E", 1)) as gw:
        r = _run(WINDOWS_LIKE, "live", gw.url, "--baud", "19200", "--parity", "E", "--headless", "--format", "jsonl",
                 "--duration", "4", "--out", "gw.mcap", cwd=tmp_path)
        assert gw.from_clients == 0
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    frames = [json.loads(x) for x in r.stdout.splitlines() if x.startswith("{") and '"raw"' in x]
    assert len(frames) > 20 and sum(f["crc_ok"] is True for f in frames) >= 0.9 * len(frames)
    info, _ = open_mcap(str(tmp_path / "gw.mcap"))
    assert info.time_source == "net"


def test_the_stand_ins_are_in_place(tmp_path):
    r = _run(WINDOWS_LIKE.replace("from sniffer.cli import main", "import os, serial\nprint(hasattr(os, 'fork'), "
                                  "multiprocessing.get_start_method())\nserial.Serial('/dev/null')"), cwd=tmp_path)
    assert r.stdout.split() == ["False", "spawn"] and "POSIX backend was used" in r.stderr
