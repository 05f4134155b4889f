"""docs/sniffer.service stays true: its command line is one this sniffer takes, and systemd reads the unit."""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sniffer.cli import build_parser
from sniffer.capture.settings import CaptureSpec

UNIT = Path(__file__).resolve().parent.parent / "docs" / "sniffer.service"


def _exec_start() -> list[str]:
    text = UNIT.read_text().replace("\\\n", " ")
    line = next(line for line in text.splitlines() if line.startswith("ExecStart="))
    return shlex.split(line[len("ExecStart="):])


def test_the_units_command_line_parses():
    argv = _exec_start()
    assert argv[0].endswith("/sniffer") and argv[1] == "live"
    args = build_parser().parse_args(argv[1:])
    assert args.ports[0].startswith("/dev/serial/by-id/") and args.wait_port and args.headless and args.quiet
    args.bus = None  # /etc/sniffer/line.toml is the field engineer's (sniffer detect --write-bus writes one)
    spec = CaptureSpec.from_args(args)
    assert spec.rotate.span_ns == 3600 * 10**9 and spec.rotate.max_bytes == 200 * 10**6
    assert spec.keep.age_ns == 14 * 86400 * 10**9 and spec.keep.max_bytes == 20 * 10**9
    assert spec.out == "/var/lib/sniffer/cab3" and spec.out.startswith("/var/lib/sniffer")  # its StateDirectory


def test_systemd_reads_the_unit(tmp_path):
    if shutil.which("systemd-analyze") is None:
        pytest.skip("systemd-analyze not installed")
    unit = tmp_path / "sniffer.service"
    exe = Path(sys.executable).with_name("sniffer")
    unit.write_text(UNIT.read_text().replace("/opt/rs485-sniffer/.venv/bin/sniffer", str(exe)))
    r = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=60)
    complaints = [line for line in (r.stdout + r.stderr).splitlines() if "sniffer.service" in line]
    assert r.returncode == 0 and not complaints, r.stdout + r.stderr
