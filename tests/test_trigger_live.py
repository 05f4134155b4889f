"""Triggers on a live capture: `sniffer simulate --pty` serves two TDS-V8 drives that trip now and then on a
pseudo-terminal, `sniffer live PATH --trigger fault --ring` captures it.  Checks what arrived, not when: each
window holds its trigger frame and the frames the live stream printed over its span, only windows were
written, and not one byte went to the line."""

import json
import os
import signal
import subprocess
import sys
import time

from helpers import frames_of, window_holds

from sniffer.triggers import read_trigger

SNIFFER = [sys.executable, "-m", "sniffer"]


def test_live_capture_on_a_pty_keeps_a_window_per_fault(tmp_path):
    link = tmp_path / "line0"
    sim = subprocess.Popen(SNIFFER + ["simulate", "--pty", str(link), "--scenario", "tds-v8", "--seed", "2"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    log = tmp_path / "ran.txt"
    try:
        deadline = time.monotonic() + 30
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        live = subprocess.run(
            SNIFFER + ["live", str(link), "--baud", "9600", "--parity", "N", "--stopbits", "2", "--headless",
                       "--format", "jsonl", "--duration", "14", "--out", str(tmp_path / "cab.mcap"),
                       "--trigger", "fault", "--pre", "2s", "--post", "1s", "--ring",
                       "--on-trigger", f'echo "$SNIFFER_TRIGGER_FILE $SNIFFER_TRIGGER_RULE" >> {log}'],
            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    finally:
        sim.send_signal(signal.SIGTERM)
        _, err = sim.communicate(timeout=30)
    assert live.returncode == 0, live.stderr
    assert "0 bytes came from the other end" in err  # passive: the sniffer wrote nothing to the line
    assert not list(tmp_path.glob("cab.mcap*"))  # --ring: no whole capture
    stream = [json.loads(x) for x in live.stdout.splitlines()]
    windows = sorted(tmp_path.glob("cab.trigger-*.mcap"))
    assert windows, live.stderr
    for w in windows:
        m = read_trigger(str(w))
        held = [(r["t"], r["raw"]) for r in frames_of(w)]
        for firing in m["firings"]:
            assert (firing["record"]["t"], firing["record"]["raw"]) in held
            assert any(a["code"] == "model.fault" for a in firing["record"]["annotations"])
        assert window_holds(held, [(r["t"], r["raw"]) for r in stream], m["start_t"], m["end_t"])
        assert m["asked_start_t"] - 1.0 <= m["start_t"] <= m["asked_start_t"] or not m["pre_complete"]
        assert m["rules"] == ["fault"] and m["firings"][0]["time"].endswith("Z")  # live: a wall clock
    ran = log.read_text().splitlines()
    assert sorted(ran) == sorted(f"{w.resolve()} fault" for w in windows)
    assert not os.path.lexists(link)
