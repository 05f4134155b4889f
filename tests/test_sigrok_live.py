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

import pytest

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


def _children(pid: int) -> list[int]:
    try:
        text = open(f"/proc/{pid}/task/{pid}/children").read()
    except OSError:
        return []
    return [int(x) for x in text.split()]


def _alive(pid: int) -> bool:
    try:
        state = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.parametrize("what", ["live", "file"])
def test_a_killed_sniffer_leaves_no_sigrok_cli_behind(what, tmp_path):
    """SIGKILL gives the sniffer no chance to stop its sigrok-cli: the kernel ends it (PR_SET_PDEATHSIG).

    live: the demo analyzer's D7 carries no bytes, so sigrok-cli writes no frame; file: 300 MB of idle samples,
    seconds of decoding with nothing to write and no stdin.  (sigrok-cli also ends on its own here: the end of file
    on its stdin, live, and the broken pipe of the log lines `-l 4` writes; the kernel's signal does not depend
    on either.)"""
    need_sigrok_cli()
    if not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_PDEATHSIG and /proc are Linux's")
    import os
    import signal
    import time

    if what == "live":
        argv = ["live", "sigrok:demo", "--rx", "D7", "--baud", "25000", "--samplerate", "100k", "--headless", "--quiet"]
    else:
        from srgen import write_sr

        write_sr(tmp_path / "idle.sr", 1_000_000, ["RX"], b"\x01" * (300 << 20), member_size=16 << 20)
        argv = ["replay", str(tmp_path / "idle.sr"), "--rx", "RX", "--baud", "9600", "--quiet"]
    proc = subprocess.Popen([sys.executable, "-m", "sniffer", *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        kids: list[int] = []
        while not kids and time.monotonic() < deadline and proc.poll() is None:
            kids = [k for k in _children(proc.pid) if "sigrok" in open(f"/proc/{k}/cmdline").read()]
            time.sleep(0.05)
        assert kids, "sigrok-cli never started under the live capture"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 2  # the kernel's signal is at once; 300 MB of samples take sigrok-cli longer
        while any(_alive(k) for k in kids) and time.monotonic() < deadline:
            time.sleep(0.05)
        left = [k for k in kids if _alive(k)]
        for k in left:
            os.kill(k, signal.SIGKILL)
        assert not left, "sigrok-cli went on acquiring after the sniffer was killed"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
