"""`sniffer live sigrok:DRIVER`: a real sigrok driver (sigrok-cli's `demo` analyzer, made by software) end to end.

Its D0 pattern at 25000 baud reads as a stream of 0x55 bytes and glitches: no
Modbus, but real bytes from a real acquisition.  The MCAP it writes keeps the
decoded bytes and the sample rate: a replay gives the very frames the live
capture printed.  The options sigrok-cli gets only read the analyzer.
"""

from __future__ import annotations

import json
import subprocess
import sys

from sigrok_tools import need_sigrok_cli

from sniffer.sources.logic_options import DeviceSpec, LogicSpec
from sniffer.sources.files import FileSource
from sniffer.sources.sigrok_cli import device_source


def sniffer(*args):
    return subprocess.run([sys.executable, "-m", "sniffer", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_a_live_capture_replays_to_the_frames_it_showed(tmp_path):
    need_sigrok_cli()
    out = tmp_path / "demo.mcap"
    live = sniffer("live", "sigrok:demo", "--rx", "D0", "--baud", 25000, "--samplerate", "100k", "--duration", 1,
                   "--headless", "--format", "jsonl", "--out", out)
    assert live.returncode == 0, live.stderr
    shown = [json.loads(x) for x in live.stdout.splitlines()]
    assert shown and sum(len(r["raw"]) for r in shown) > 100
    assert all(r["time_source"] == "byte" for r in shown)
    replay = sniffer("replay", out, "--format", "jsonl")
    assert replay.returncode == 0, replay.stderr
    assert [json.loads(x) for x in replay.stdout.splitlines()] == shown
    info = FileSource(out).open()
    assert info.extra["samplerate"] == 100_000 and info.extra["sigrok"] == {"device": "sigrok:demo"}
    assert info.wall_anchor_ns > 0 and info.baud == 25000


def test_the_analyzer_is_only_read():
    """Sample rate, continuous acquisition and the channels in use: no --set, no output file, no other -c."""
    need_sigrok_cli()
    src = device_source(DeviceSpec.parse("sigrok:demo"), LogicSpec("D0", "D1", "D2", samplerate=2_000_000,
                                                                   baud=9600))
    assert src.acquire == ["-d", "demo", "-c", "samplerate=2000000", "--continuous", "-C", "D0,D1,D2"]
    assert src.live and src.samplerate == 2_000_000
    argv = src.argv
    assert not {"--set", "-o", "--output-file", "-O", "--output-format", "-t", "--triggers"} & set(argv)
    assert [argv[i + 1] for i, a in enumerate(argv) if a == "-c"] == ["samplerate=2000000"]
