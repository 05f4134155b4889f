"""The MQTT bridge without a broker: which frames become which messages (sniffer/mqtt/bridge.py)."""

from __future__ import annotations

import json

import pytest
from helpers import bursts, fr, run_events

from sniffer.events import CaptureInfo
from sniffer.line import LineSettings, SettingsError
from sniffer.mqtt.bridge import Bridge
from sniffer.mqtt.options import MqttSpec, parse_url

LINE = LineSettings(19200, "N", 1)
READ = [fr("010321000002"), fr("0103040109" "0af0")]  # unit 1 reads holding 8448..8449: 265, 2800
WRITE = fr("010620000bb8")  # unit 1 writes holding 8192 = 3000; the echo acknowledges it


def spec(**kw) -> MqttSpec:
    s = parse_url("mqtt://127.0.0.1/plant/line3")
    return MqttSpec(**{**s.__dict__, **kw})


def publish(frames_hex, *, gap_chars=5.0, finish=True, **kw) -> tuple[Bridge, list]:
    frames = run_events(bursts(frames_hex, LINE, gap_chars), LINE)
    b = Bridge(spec(**kw), CaptureInfo(baud=19200, wall_anchor_ns=1_700_000_000 * 10**9))
    out = [m for f in frames for m in b.frame(f)]
    if finish:
        out += b.finish()
    return b, out


def values(msgs) -> dict[str, list[dict]]:
    got: dict[str, list[dict]] = {}
    for m in msgs:
        if m.retain and not m.topic.endswith(("/health", "/status")):
            got.setdefault(m.topic, []).append(json.loads(m.payload))
    return got


def test_a_read_response_publishes_each_register_retained_with_its_quality_and_time():
    _, msgs = publish(READ)
    v = values(msgs)
    assert sorted(v) == ["plant/line3/default/1/holding_8448", "plant/line3/default/1/holding_8449"]
    p = v["plant/line3/default/1/holding_8449"][0]
    assert (p["value"], p["raw"], p["address"], p["name"]) == (2800, 2800, 8449, "holding[8449]")
    assert p["quality"] == {"crc_ok": True, "annotations": []}
    assert p["time"].startswith("2023-11-14T22:13:20.") and p["time"].endswith("Z")
    assert p["epoch"] == pytest.approx(1_700_000_000 + p["t"], abs=1e-6)
    assert p["written"] is False and p["frame"] == 1


def test_a_write_is_published_once_its_acknowledgement_came():
    v = values(publish([WRITE, WRITE])[1])
    (p,) = v["plant/line3/default/1/holding_8192"]
    assert (p["value"], p["written"], p["frame"]) == (3000, True, 1)  # the echo's frame confirms the request's value


@pytest.mark.parametrize("answer", [
    pytest.param(WRITE[:-4] + "0000", id="crc-bad-echo"),
    pytest.param(fr("018602"), id="exception"),
    pytest.param(None, id="no-answer"),
])
def test_a_write_not_acknowledged_is_never_published(answer):
    frames = [WRITE] + ([answer] if answer else []) + READ  # the read after it is published as usual
    _, msgs = publish(frames, gap_chars=2000 if answer is None else 5.0)
    v = values(msgs)
    assert "plant/line3/default/1/holding_8192" not in v
    assert "plant/line3/default/1/holding_8448" in v


def test_a_crc_bad_response_publishes_no_value_but_an_event():
    bad = READ[1][:-4] + "0000"
    _, msgs = publish([READ[0], bad])
    assert values(msgs) == {}
    events = [json.loads(m.payload) for m in msgs if m.topic == "plant/line3/default/events"]
    assert any(e["code"] == "modbus.crc.mismatch" and e["unit"] == 1 for e in events)
    assert all(not m.retain for m in msgs if m.topic.endswith("/events"))


def test_health_counts_requests_responses_errors_and_latency():
    bad = READ[1][:-4] + "0000"
    _, msgs = publish(READ + READ + [READ[0], bad])
    (last,) = [json.loads(m.payload) for m in msgs if m.topic == "plant/line3/default/1/health"][-1:]
    assert (last["requests"], last["responses"], last["crc_errors"]) == (3, 3, 1)
    assert last["errors"] >= 1 and last["latency_ms"]["median"] > 0


def test_changes_only_sends_a_value_that_changed():
    other = [READ[0], fr("0103040109" "0af1")]
    b, msgs = publish(READ + READ + other + READ, changes=True)
    v = values(msgs)
    assert [p["raw"] for p in v["plant/line3/default/1/holding_8449"]] == [2800, 2801, 2800]
    assert [p["raw"] for p in v["plant/line3/default/1/holding_8448"]] == [265]
    assert b.suppressed == 4  # 8449: one 2800 again; 8448: three 265s again


def test_the_interval_keeps_one_value_per_topic_and_sends_the_newest_at_the_end():
    polls = []
    for raw in range(2800, 2810):
        polls += [READ[0], fr(f"0103040109{raw:04x}")]
    b, msgs = publish(polls, interval_s=3600.0, finish=False)  # a whole hour: only the first goes out now
    assert [p["raw"] for p in values(msgs)["plant/line3/default/1/holding_8449"]] == [2800]
    last = values(b.finish())["plant/line3/default/1/holding_8449"]
    assert [p["raw"] for p in last] == [2809]  # the newest value, held back, goes out at the end


def test_an_interval_over_sends_the_held_value_when_capture_time_moves_on():
    polls = []
    for raw in (2800, 2801):
        polls += [READ[0], fr(f"0103040109{raw:04x}")]
    b, msgs = publish(polls, interval_s=1.0, finish=False)
    assert len(values(msgs)["plant/line3/default/1/holding_8449"]) == 1
    later = b.advance(b.now + 2 * 10**9)  # a quiet line: the session's advance(t) still moves time on
    assert [p["raw"] for p in values(later)["plant/line3/default/1/holding_8449"]] == [2801]


def test_home_assistant_discovery_names_and_tags_a_models_registers():
    from sniffer.capture.session import decode_capture

    session = decode_capture("captures/sim/a510.mcap")
    b = Bridge(spec(ha_prefix="homeassistant"), session.info)
    msgs = [m for f in session for m in b.frame(f)]
    configs = {m.topic: json.loads(m.payload) for m in msgs if m.topic.startswith("homeassistant/")}
    assert all(m.retain for m in msgs if m.topic.startswith("homeassistant/"))
    node = "sniffer_plant_line3_default_u1"
    freq = configs[f"homeassistant/sensor/{node}/output_frequency/config"]
    assert (freq["name"], freq["unit_of_measurement"], freq["device_class"]) == ("Output frequency", "Hz", "frequency")
    assert freq["state_topic"] == "plant/line3/default/1/output_frequency"
    assert freq["availability_topic"] == "plant/line3/status"
    assert freq["device"]["identifiers"] == [node] and freq["device"]["model_id"] == "a510"
    cur = configs[f"homeassistant/sensor/{node}/output_current/config"]
    assert (cur["unit_of_measurement"], cur["device_class"]) == ("A", "current")
    fault = configs[f"homeassistant/sensor/{node}/error_description_fault_code/config"]
    assert "value_json.text" in fault["value_template"] and "unit_of_measurement" not in fault
    assert f"homeassistant/sensor/{node}/health/config" in configs
    # each config comes before the first value on its state topic
    order = [m.topic for m in msgs]
    assert order.index(f"homeassistant/sensor/{node}/output_frequency/config") < order.index(freq["state_topic"])


def test_a_name_the_model_gives_several_registers_gets_the_address_in_every_topic():
    from sniffer.mqtt.sink import MqttSink
    from sniffer.capture.session import decode_capture

    session = decode_capture("captures/sim/a510.mcap")
    sink = MqttSink(spec(ha_prefix="homeassistant"), registry=session.registry)
    b = Bridge(sink.spec, session.info, model_name=sink._model_name, shared_names=sink._shared_names)
    msgs = [m for f in session for m in b.frame(f)]
    topics = {m.topic for m in msgs}
    # A510: "Frequency command" is 2502H (written) and 2523H (monitored): two topics, neither bare
    assert {"plant/line3/default/1/frequency_command_9474", "plant/line3/default/1/frequency_command_9507"} <= topics
    assert "plant/line3/default/1/frequency_command" not in topics
    dev = json.loads(next(m.payload for m in msgs if m.topic.endswith("u1/output_frequency/config")))["device"]
    assert dev["model"] == "TECO A510 inverter" and dev["name"] == "TECO A510 inverter unit 1"


@pytest.mark.parametrize("url, says", [
    ("http://host/p", "give mqtt://HOST[:PORT]/PREFIX"),
    ("mqtt://host", "no topic prefix"),
    ("mqtt:///plant", "no broker host"),
    ("mqtt://host:99999/p", "Port out of range"),
    ("mqtt://host/plant/#", "may not hold '#'"),
    ("mqtt://u:pw@host:x/p", "--mqtt mqtt://u:***@host:x/p"),  # the password never in a message
    ("mqtt://a b/x", "'a b' is not a host name or address"),  # urlsplit takes it: it would fail at connect
    ("mqtt://-plc/x", "'-plc' is not a host name or address"),
])
def test_a_bad_url_is_one_line_naming_what_is_wrong(url, says):
    with pytest.raises(SettingsError) as e:
        parse_url(url)
    assert says in str(e.value) and "\n" not in str(e.value)
    assert "pw@" not in str(e.value)


def test_url_defaults_and_the_password_from_the_environment(monkeypatch):
    monkeypatch.setenv("SNIFFER_MQTT_PASSWORD", "from-env")
    s = parse_url("mqtts://plc@broker.local/plant/line%203/")
    assert (s.host, s.port, s.tls, s.prefix, s.username, s.password) == (
        "broker.local", 8883, True, "plant/line 3", "plc", "from-env")
    assert parse_url("mqtt://[::1]/p").broker == "[::1]:1883"


class _OnLink:
    """A frame of a capture of several links (frames carry `link` there; sniffer.capture.links)."""

    def __init__(self, f, link: str) -> None:
        self._f = f
        self.link = link

    def __getattr__(self, name):
        return getattr(self._f, name)


def test_each_link_has_its_own_topics_health_and_devices():
    frames = run_events(bursts(READ, LINE), LINE)
    b = Bridge(spec(ha_prefix="homeassistant"), CaptureInfo(baud=19200))
    msgs = [m for link in ("Cab 3", "") for f in frames for m in b.frame(_OnLink(f, link))] + b.finish()
    topics = {m.topic for m in msgs}
    assert {"plant/line3/cab_3/1/holding_8449", "plant/line3/default/1/holding_8449",
            "plant/line3/cab_3/1/health", "plant/line3/default/1/health"} <= topics
    dev = {json.loads(m.payload)["device"]["name"] for m in msgs if m.topic.endswith("/config")}
    assert dev == {"generic unit 1 (Cab 3)", "generic unit 1"}
