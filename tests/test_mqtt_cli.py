"""--mqtt on every capture command: declared once, carried to a capture process, demo end to end."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from broker import make_ca, make_server_cert, retained

from sniffer.cli import build_parser
from sniffer.mqtt.options import MqttSpec
from sniffer.capture.settings import CaptureSpec


def test_the_mqtt_flags_travel_to_a_capture_process_unchanged(tmp_path):
    """live/demo with the TUI and serve start the capture as a process of its own, its CaptureSpec whole."""
    make_ca(tmp_path)
    cert, key = make_server_cert(tmp_path)  # any certificate and key will do as a client's
    argv = ["live", "/dev/ttyUSB0", "--mqtt", "mqtts://plc:pw@broker.local:8884/plant/line3", "--mqtt-ca",
            str(tmp_path / "ca.pem"), "--mqtt-cert", str(cert), "--mqtt-key", str(key), "--mqtt-interval", "2s",
            "--mqtt-changes", "--mqtt-ha", "--mqtt-queue", "500"]  # --mqtt-ha before nothing: no PREFIX eaten
    spec = CaptureSpec.from_args(build_parser().parse_args(argv))
    m = spec.mqtt
    assert (m.host, m.port, m.tls, m.prefix, m.username, m.password) == (
        "broker.local", 8884, True, "plant/line3", "plc", "pw")
    assert (m.interval_s, m.changes, m.ha_prefix, m.queue) == (2.0, True, "homeassistant", 500)
    assert CaptureSpec.decode(spec.encode()).mqtt == spec.mqtt  # the password with it, never in argv
    plain = CaptureSpec.from_args(build_parser().parse_args(["demo", "--mqtt", "mqtt://h/p"]))
    assert CaptureSpec.decode(plain.encode()).mqtt == plain.mqtt
    assert CaptureSpec.from_args(build_parser().parse_args(["demo"])).mqtt is None


@pytest.mark.parametrize("command", [["live", "/dev/ttyUSB0"], ["demo"], ["replay", "x.mcap"], ["serve", "--demo"]])
def test_every_capture_command_takes_the_flags(command):
    args = build_parser().parse_args([*command, "--mqtt", "mqtt://h/p", "--mqtt-ha", "--mqtt-ha-prefix", "ha"])
    assert CaptureSpec.from_args(args).mqtt == MqttSpec("mqtt://h/p", "h", 1883, "p", ha_prefix="ha")


def test_demo_publishes_what_the_live_capture_decodes(mqtt_broker, tmp_path):
    r = subprocess.run([sys.executable, "-m", "sniffer", "demo", "--headless", "--quiet", "--scenario", "a510",
                        "--duration", "3", "--out", str(tmp_path / "demo.mcap"), "--mqtt", mqtt_broker.url("site/a"),
                        "--mqtt-ha", "--mqtt-changes"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    got = retained(mqtt_broker)
    v = json.loads(got["site/a/default/1/output_frequency"])
    assert v["unit"] == "Hz" and v["time"].endswith("Z") and v["epoch"] > 1.6e9  # a live capture knows its clock
    cfg = json.loads(got["homeassistant/sensor/sniffer_site_a_default_u1/output_frequency/config"])
    assert cfg["device"]["model"] == "TECO A510 inverter"
    # the MCAP holds the same capture: its last frequency is the retained one
    rep = subprocess.run([sys.executable, "-m", "sniffer", "replay", str(tmp_path / "demo.mcap"), "--format", "jsonl"],
                         capture_output=True, text=True, timeout=120)
    last = None
    for line in rep.stdout.splitlines():
        rec = json.loads(line)
        if rec["unit"] == 1 and rec["role"] == "response" and rec["crc_ok"] and not rec["exception"]:
            last = next((p["raw"] for p in rec["points"] if p["name"] == "Output frequency"), last)
    assert v["raw"] == last


def test_the_sinks_status_says_what_the_client_did(mqtt_broker):
    from sniffer.capture.session import CaptureSpec as Spec
    from sniffer.capture.session import decode_capture

    spec = Spec(mqtt=MqttSpec.from_args(build_parser().parse_args(["replay", "x", "--mqtt", mqtt_broker.url()])))
    session = decode_capture("captures/sim/a510.mcap", spec)
    session.run()
    st = session.sinks[-1].status()["mqtt"]
    assert st["broker"] == f"127.0.0.1:{mqtt_broker.port}" and st["dropped"] == 0 and st["queued"] == 0
    assert st["published"] > st["topics"] > 20 and st["values"] > st["topics"] and st["connects"] == 1


def test_the_status_file_has_the_mqtt_section(mqtt_broker, tmp_path):
    status = tmp_path / "status.json"
    r = subprocess.run([sys.executable, "-m", "sniffer", "demo", "--headless", "--quiet", "--duration", "2", "--no-out",
                        "--status", str(status), "--mqtt", mqtt_broker.url(), "--mqtt-queue", "100000"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    st = json.loads(status.read_text())
    m = st["mqtt"]
    assert st["state"] == "ended" and m["broker"] == f"127.0.0.1:{mqtt_broker.port}"
    assert m["published"] > 0 and m["dropped"] == 0 and m["queued"] == 0 and m["connected"] is False
    shown = subprocess.run([sys.executable, "-m", "sniffer", "status", str(status)], capture_output=True, text=True,
                           timeout=60)
    assert "mqtt" in shown.stdout and str(m["published"]) in shown.stdout, shown.stdout + shown.stderr
