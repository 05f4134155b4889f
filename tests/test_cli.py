"""The command line as a user meets it: real subprocesses, real files.

Bad input: one clear error line on stderr, exit code 2, never a traceback.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest
from refdata import SIGROK

SNIFFER = [sys.executable, "-m", "sniffer"]


def run(*args, timeout=120, **kw):
    return subprocess.run(SNIFFER + list(args), capture_output=True, text=True, timeout=timeout, **kw)


def _one_error_line(r):
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("sniffer: error:"), r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(
    "args",
    [
        ["replay", "/nonexistent/file.mcap"],
        ["replay", str(SIGROK / "wizmodbus.json")],  # not a capture
        ["replay", str(SIGROK / "wizmodbus.bytes.csv")],  # CSV carries no baud: flags required
        ["replay", str(SIGROK / "wizmodbus.bytes.csv"), "--baud", "9600", "--device", "1=nosuchmodel"],
        ["replay", str(SIGROK / "wizmodbus.bytes.csv"), "--baud", "-5"],
        ["replay", str(SIGROK / "wizmodbus.bytes.csv"), "--parity", "X"],
        ["live", "/dev/does-not-exist", "--no-out"],
        ["decode", "zz11"],
        ["frobnicate"],
        ["simulate", "--out", "x.mcap", "--scenario", "nosuch"],
    ],
)
def test_bad_input_one_line_exit_2(args, tmp_path):
    _one_error_line(run(*args, cwd=tmp_path))


def test_corrupt_mcap_one_line(tmp_path):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + os.urandom(300))
    _one_error_line(run("replay", str(bad)))


def test_replay_sigrok_csv_jsonl_contract():
    r = run("replay", str(SIGROK / "wizmodbus.bytes.csv"), "--baud", "9600", "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    recs = [json.loads(l) for l in r.stdout.splitlines()]
    assert len(recs) == 88
    keys = {"t", "raw", "protocol", "unit", "function", "role", "crc_ok", "exception", "model",
            "points", "annotations", "latency_ms", "pair"}
    for rec in recs:
        assert keys <= rec.keys()
        for a in rec["annotations"]:
            assert {"code", "severity", "detail"} <= a.keys()
        for p in rec["points"]:
            assert {"name", "address", "raw", "value", "unit"} <= p.keys()
    assert recs[0]["role"] == "request" and recs[1]["pair"] == 0 and recs[1]["latency_ms"] > 2.0


def test_decode_hex_pairs_request_and_response():
    r = run("decode", "010300000002C40B", "010304000100022A32", "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    req, rsp = (json.loads(l) for l in r.stdout.splitlines())
    assert (req["role"], rsp["role"], rsp["pair"]) == ("request", "response", 0)
    assert [(p["address"], p["value"]) for p in rsp["points"]] == [(0, 1), (1, 2)]


def test_simulate_then_replay_mcap_and_csv_agree(tmp_path):
    mc, cs = tmp_path / "s.mcap", tmp_path / "s.csv"
    assert run("simulate", "--out", str(mc), "--scenario", "errors", "--duration", "3", "--seed", "3").returncode == 0
    assert run("simulate", "--out", str(cs), "--scenario", "errors", "--duration", "3", "--seed", "3").returncode == 0
    a = run("replay", str(mc), "--format", "jsonl")
    b = run("replay", str(cs), "--baud", "19200", "--parity", "E", "--format", "jsonl")
    assert a.returncode == 0 and b.returncode == 0, (a.stderr, b.stderr)
    ra = [json.loads(l) for l in a.stdout.splitlines()]
    rb = [json.loads(l) for l in b.stdout.splitlines()]
    assert [r["raw"] for r in ra] == [r["raw"] for r in rb]
    assert any(r["crc_ok"] is False for r in ra) and any(r["exception"] for r in ra)


def test_sigkilled_live_capture_replays_and_repairs(tmp_path):
    """`sniffer demo` (a live capture of the simulated bus over a pty) killed with SIGKILL."""
    out = tmp_path / "killed.mcap"
    proc = subprocess.Popen(SNIFFER + ["demo", "--headless", "--duration", "60", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 30
        part = tmp_path / "killed.mcap.part"  # written under that name until the capture ends
        while time.monotonic() < deadline and (not part.exists() or part.stat().st_size < 20_000):
            time.sleep(0.2)
        time.sleep(1.5)  # at least one more periodic flush
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    assert not out.exists() and part.exists()
    r = run("replay", str(out), "--format", "jsonl")  # the name the user gave: its part file is read
    assert r.returncode == 0, r.stderr
    assert "killed.mcap.part" in r.stderr and "did not end cleanly" in r.stderr
    recs = [json.loads(l) for l in r.stdout.splitlines()]
    assert len(recs) > 20 and all(rec["crc_ok"] for rec in recs if rec["protocol"] != "noise")
    fixed = tmp_path / "fixed.mcap"
    r = run("repair", str(out), "-o", str(fixed))
    assert r.returncode == 0, r.stderr
    from mcap.reader import make_reader

    with open(fixed, "rb") as fh:
        n = sum(1 for _ in make_reader(fh).iter_messages(topics=["/raw"]))
    assert n > 20


def test_ctrl_c_closes_the_capture_cleanly(tmp_path):
    """SIGINT (Ctrl-C) during a live capture: exit 0, a finished MCAP any reader opens."""
    out = tmp_path / "stopped.mcap"
    proc = subprocess.Popen(SNIFFER + ["demo", "--headless", "--duration", "60", "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 30
        part = tmp_path / "stopped.mcap.part"  # written under that name until the capture ends (the final name
        # only appears at the end: waiting on it waited the whole deadline)
        while time.monotonic() < deadline and (not part.exists() or part.stat().st_size < 10_000):
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "frames" in err
    from mcap.reader import make_reader

    with open(out, "rb") as fh:
        reader = make_reader(fh)
        assert reader.get_summary() is not None  # finished: summary and footer written
        assert sum(1 for _ in reader.iter_messages(topics=["/frames"])) > 10


def test_simulate_help_names_every_scenario():
    from sniffer.commands.flags import scenario_help
    from sniffer.simulator.scenario import SCENARIOS

    assert scenario_help().split(": ", 1)[1].split(", ") == list(SCENARIOS)
