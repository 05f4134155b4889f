"""--mqtt against a real mosquitto (tests/broker.py): topics, payloads, retained flags, HA discovery,
users and TLS, a broker that is not there or goes away.  Runs `sniffer` as a user would."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from broker import Broker, Subscriber, make_ca, retained

A510 = "captures/sim/a510.mcap"


def sniffer(*args, timeout=120, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sniffer", *args], capture_output=True, text=True, timeout=timeout,
                          **kw)


def replay_frames(path) -> int:
    r = sniffer("replay", str(path), "--format", "jsonl")
    assert r.returncode == 0, r.stderr
    return len(r.stdout.splitlines())


def test_replay_publishes_retained_values_health_and_discovery(mqtt_broker):
    r = sniffer("replay", A510, "--quiet", "--mqtt", mqtt_broker.url(), "--mqtt-ha")
    assert r.returncode == 0, r.stderr
    assert "mqtt: connected to 127.0.0.1:" in r.stderr and "Traceback" not in r.stderr
    got = retained(mqtt_broker)
    v = json.loads(got["plant/line3/default/1/output_frequency"])
    assert v["unit"] == "Hz" and v["value"] == pytest.approx(v["raw"] / 100) and v["quality"]["crc_ok"] is True
    assert set(v) >= {"value", "unit", "raw", "time", "epoch", "t", "quality", "name", "frame"}
    fault = json.loads(got["plant/line3/default/2/error_description_fault_code"])
    assert isinstance(fault["text"], str) and fault["text"]
    health = json.loads(got["plant/line3/default/1/health"])
    assert health["responses"] > 0 and health["latency_ms"]["median"] > 0
    cfg = json.loads(got["homeassistant/sensor/sniffer_plant_line3_default_u2/output_current/config"])
    assert (cfg["unit_of_measurement"], cfg["device_class"], cfg["state_topic"]) == (
        "A", "current", "plant/line3/default/2/output_current")
    assert got["plant/line3/status"] == b"offline"  # the capture ended: its sensors show unavailable
    assert not any(t.endswith("/events") for t in got)  # events are never retained


@pytest.mark.parametrize("queue", [None, 5])
def test_the_last_retained_value_is_the_captures_last_confirmed_one(mqtt_broker, queue):
    """Also when the queue overflows (5 messages: most are dropped): a retained value dropped goes out again."""
    r = sniffer("replay", A510, "--format", "jsonl")
    last = {}
    for line in r.stdout.splitlines():
        rec = json.loads(line)
        if rec["role"] == "response" and rec["crc_ok"] and not rec["exception"]:
            for p in rec["points"]:
                if p["name"] == "Output frequency":
                    last[rec["unit"]] = p["raw"]
    flags = ["--mqtt-queue", str(queue)] if queue else []
    run = sniffer("replay", A510, "--quiet", "--mqtt", mqtt_broker.url(), *flags)
    assert run.returncode == 0, run.stderr
    assert ("dropped (queue full)" in run.stderr) == bool(queue), run.stderr
    got = retained(mqtt_broker, "plant/line3/+/+/output_frequency")
    assert {int(t.split("/")[3]): json.loads(p)["raw"] for t, p in got.items()} == last


def test_events_go_out_unretained_as_they_happen(mqtt_broker, tmp_path):
    cap = tmp_path / "errors.mcap"
    assert sniffer("simulate", "--scenario", "errors", "--duration", "5", "--out", str(cap)).returncode == 0
    sub = Subscriber(mqtt_broker, "plant/line3/default/events")
    try:
        r = sniffer("replay", str(cap), "--quiet", "--mqtt", mqtt_broker.url())
        assert r.returncode == 0, r.stderr
        got = sub.wait_for(lambda g: g, what="events")
    finally:
        sub.close()
    codes = {json.loads(p)["code"] for t, p, _ in sub.messages}
    assert {"modbus.crc.mismatch", "pair.timeout"} & codes and len(got) == 1
    assert not any(r for _, _, r in sub.messages)


def test_a_user_and_password(tmp_path):
    b = Broker(tmp_path, users={"plc": "s3cr#t"}).start()
    try:
        good = sniffer("replay", A510, "--quiet", "--mqtt", b.url(user="plc", password="s3cr%23t"))
        assert good.returncode == 0 and "connected" in good.stderr, good.stderr
        assert "plant/line3/default/1/output_frequency" in retained(b, user="plc", password="s3cr#t")
        # the password from the environment (then it is not in the process list)
        env = {"SNIFFER_MQTT_PASSWORD": "s3cr#t", "PATH": "/usr/bin:/bin"}
        r = sniffer("replay", A510, "--quiet", "--mqtt", b.url("env", user="plc"), env=env)
        assert "mqtt: connected" in r.stderr, r.stderr
        bad = sniffer("replay", A510, "--quiet", "--mqtt", b.url(user="plc", password="wrong"))
    finally:
        b.stop()
    assert bad.returncode == 0  # the capture is what matters: it ran to its end
    lines = [x for x in bad.stderr.splitlines() if "mqtt" in x]
    assert any("refused the connection" in x and "authorized" in x.lower() for x in lines), bad.stderr
    assert "wrong" not in bad.stderr and "Traceback" not in bad.stderr


def test_tls_with_the_brokers_ca_and_a_wrong_one(tmp_path):
    b = Broker(tmp_path, tls=True).start()
    try:
        ok = sniffer("replay", A510, "--quiet", "--mqtt", b.url(), "--mqtt-ca", str(b.ca))
        assert ok.returncode == 0 and "mqtt: connected" in ok.stderr, ok.stderr
        assert "plant/line3/default/1/output_frequency" in retained(b)
        other = make_ca(tmp_path / "other", "other")
        bad = sniffer("replay", A510, "--quiet", "--mqtt", b.url(), "--mqtt-ca", str(other))
    finally:
        b.stop()
    assert bad.returncode == 0 and "Traceback" not in bad.stderr
    assert any("TLS:" in x and "certificate" in x for x in bad.stderr.splitlines()), bad.stderr


def test_tls_with_a_client_certificate(tmp_path):
    b = Broker(tmp_path, tls=True, client_certs=True).start()
    try:
        without = sniffer("replay", A510, "--quiet", "--mqtt", b.url(), "--mqtt-ca", str(b.ca))
        ok = sniffer("replay", A510, "--quiet", "--mqtt", b.url(), "--mqtt-ca", str(b.ca),
                     "--mqtt-cert", str(b.client_cert), "--mqtt-key", str(b.client_key))
        assert ok.returncode == 0 and "mqtt: connected" in ok.stderr, ok.stderr
        assert "plant/line3/default/1/output_frequency" in retained(b)
    finally:
        b.stop()
    assert without.returncode == 0 and "mqtt: connected" not in without.stderr
    assert "mqtt: cannot connect" in without.stderr and "Traceback" not in without.stderr, without.stderr


@pytest.mark.parametrize("flags, says", [
    (["--mqtt", "mqtt://127.0.0.1"], "no topic prefix"),
    (["--mqtt", "mqtts://127.0.0.1/p", "--mqtt-ca", "missing.pem"], "--mqtt-ca missing.pem: no such file"),
    (["--mqtt", "mqtts://127.0.0.1/p", "--mqtt-ca", "README.md"], "not a CA certificate"),
    (["--mqtt", "mqtts://127.0.0.1/p", "--mqtt-cert", "README.md"], "not a certificate and its private key"),
    (["--mqtt", "mqtt://127.0.0.1/p", "--mqtt-ca", "README.md"], "needs an mqtts:// URL"),
    (["--mqtt-ha"], "--mqtt-ha needs --mqtt URL"),
    (["--mqtt", "mqtt://127.0.0.1/p", "--mqtt-ha-prefix", "ha"], "--mqtt-ha-prefix needs --mqtt-ha"),
    (["--mqtt", "mqtt://127.0.0.1/p", "--mqtt-ha", "--mqtt-ha-prefix", "ha/#"], "--mqtt-ha-prefix 'ha/#'"),
    (["--mqtt", "mqtt://127.0.0.1/p", "--mqtt-interval", "soon"], "--mqtt-interval 'soon'"),
])
def test_bad_flags_are_one_line_and_exit_2(flags, says):
    r = sniffer("replay", A510, "--quiet", *flags)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and says in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_broker_that_is_not_there_never_stops_the_capture(tmp_path):
    from broker import free_port

    port = free_port()  # nobody listens
    r = sniffer("replay", A510, "--format", "jsonl", "--mqtt", f"mqtt://127.0.0.1:{port}/p")
    assert r.returncode == 0 and len(r.stdout.splitlines()) == replay_frames(A510)
    lines = [x for x in r.stderr.splitlines() if "mqtt" in x]
    assert lines[0] == f"sniffer: mqtt: cannot connect to 127.0.0.1:{port}: Connection refused; retrying " \
                       "(the capture goes on)"
    assert "not delivered" in r.stderr and "Traceback" not in r.stderr


def test_a_broker_that_accepts_but_never_answers_never_stops_the_capture():
    import socket

    with socket.socket() as s:  # listens, never reads: the CONNECT waits for an answer that never comes
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        r = sniffer("replay", A510, "--format", "jsonl", "--mqtt", f"mqtt://127.0.0.1:{s.getsockname()[1]}/p")
    assert r.returncode == 0 and len(r.stdout.splitlines()) == replay_frames(A510)
    assert "Traceback" not in r.stderr


def test_a_broker_that_goes_away_mid_capture_loses_no_retained_state_and_no_frame(tmp_path, mqtt_broker):
    """A live capture on a pty: the broker stops, the bus goes on (the queue fills: drops, counted), the
    broker comes back empty (no persistence): the client republishes every retained value; every frame
    sent was captured, and the sniffer wrote nothing to the bus."""
    import threading
    import time
    from dataclasses import replace

    from helpers import ListSink

    from sniffer.line import LineSettings
    from sniffer.mqtt.options import parse_url
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.simulator.bus import simulate
    from sniffer.simulator.ptybus import PtyBus
    from sniffer.simulator.scenario import get_scenario
    from sniffer.sources.serial_live import SerialSource

    line = LineSettings(19200, "E", 1)
    sent = list(simulate(get_scenario("default"), line, 3.0, seed=7))
    parts = [sent[: len(sent) // 3], sent[len(sent) // 3: 2 * len(sent) // 3], sent[2 * len(sent) // 3:]]
    spec = CaptureSpec(duration_s=60, mqtt=replace(parse_url(mqtt_broker.url()), queue=20))
    collector = ListSink()
    stop = threading.Event()
    seen: dict = {}

    def until(cond, what):
        deadline = time.monotonic() + 30
        while not cond():
            if time.monotonic() > deadline:
                seen["failed"] = what
                return False
            time.sleep(0.02)
        return True

    with PtyBus() as bus:
        session = Session(spec, SerialSource(bus.port, line, reconnect=False, low_latency=False), [collector],
                          stop=stop, keep_partial=True)
        session.open()
        sink = session.sinks[-1]
        pub = sink.publisher

        def play():
            try:
                bus.play(parts[0], speed=4.0)
                if not until(lambda: pub.published > 20 and not pub.q.qsize(), "values published"):
                    return
                seen["before"] = dict(pub.retained)
                mqtt_broker.stop()
                if not until(lambda: not pub.connected, "the client noticing the broker gone"):
                    return
                bus.play(parts[1], speed=4.0)  # the bus goes on while the broker is away
                seen["dropped"] = pub.dropped
                mqtt_broker.start()
                if not until(lambda: pub.connects >= 2, "a reconnect"):
                    return
                seen["after"] = retained(mqtt_broker, live=True)  # the restarted broker has the state again
                bus.play(parts[2], speed=4.0)
            finally:
                stop.wait(0.5)
                stop.set()

        threading.Thread(target=play, daemon=True).start()
        session.run()
        bus.drain()
        written_back = bus.bytes_received_from_sniffer
    assert "failed" not in seen, seen.get("failed")
    assert session.error is None and written_back == 0
    assert [r["raw"] for r in collector.records] == [f.raw.hex() for f in sent]  # every frame captured
    assert seen["dropped"] > 0
    before = {t for t in seen["before"] if "/default/" in t}
    assert before and before <= set(seen["after"])  # every value the broker had before, back after reconnect
    st = sink.status()["mqtt"]
    assert st["dropped"] >= seen["dropped"] and st["connects"] == 2 and st["connected"] is False
    final = retained(mqtt_broker)
    assert {t: p for t, p in pub.retained.items()} == {t: final[t] for t in pub.retained}  # the latest of each


def test_a_capture_of_several_links_publishes_each_links_units_apart(tmp_path, mqtt_broker):
    """`live P1 P2 --mqtt`: two simulated lines (`simulate --pty`), unit 1 on each: two topics trees, two
    Home Assistant devices."""
    import os
    import signal
    import time

    paths = [str(tmp_path / "drives"), str(tmp_path / "pumps")]
    sims = [subprocess.Popen([sys.executable, "-m", "sniffer", "simulate", "--pty", p, "--seed", str(i)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i, p in enumerate(paths)]
    try:
        deadline = time.monotonic() + 30
        while not all(os.path.exists(p) for p in paths) and time.monotonic() < deadline:
            time.sleep(0.05)
        r = sniffer("live", *paths, "--baud", "19200", "--parity", "E", "--duration", "3", "--headless", "--quiet",
                    "--no-out", "--mqtt", mqtt_broker.url(), "--mqtt-ha")
    finally:
        for p in sims:
            p.send_signal(signal.SIGTERM)
            p.communicate(timeout=30)
    assert r.returncode == 0, r.stderr
    got = retained(mqtt_broker)
    for link in ("drives", "pumps"):
        assert f"plant/line3/{link}/1/health" in got
        assert any(t.startswith(f"plant/line3/{link}/1/holding_") for t in got)
        cfg = json.loads(got[f"homeassistant/sensor/sniffer_plant_line3_{link}_u1/health/config"])
        assert cfg["device"]["name"] == f"generic unit 1 ({link})" and cfg["device"]["suggested_area"] == link
    assert not any("/default/" in t for t in got)
