"""Home Assistant MQTT discovery (`--mqtt-ha`, `--mqtt-ha-prefix`): each drive a device, each register a sensor.

    HA_PREFIX/sensor/NODE/OBJECT/config      retained, one per register, sent before its first value

NODE is `sniffer_PREFIX_LINK_uUNIT` slugged (one device per unit of a link), OBJECT the register's
topic name.  The sensor is named after the register (the model's name), tagged with its unit and a
device class where Home Assistant has one (Hz frequency, A current, V voltage ...); a register the
model describes in words (a fault code, a status word) shows its text (`OC - Over current`), not its
number.  Availability is PREFIX/status (online / offline, the client's last will), so a sniffer that
stops shows its sensors unavailable.  Each device also gets a health sensor (the unit's median
response latency, with the counts as attributes).
"""

from __future__ import annotations

import re

import orjson

from sniffer import __version__

# the register's unit -> (device_class, unit Home Assistant expects); other units: no device class
DEVICE_CLASS = {
    "Hz": ("frequency", "Hz"), "kHz": ("frequency", "kHz"),
    "A": ("current", "A"), "mA": ("current", "mA"),
    "V": ("voltage", "V"), "mV": ("voltage", "mV"),
    "W": ("power", "W"), "kW": ("power", "kW"),
    "kWh": ("energy", "kWh"), "Wh": ("energy", "Wh"), "MWh": ("energy", "MWh"),
    "°C": ("temperature", "°C"), "degC": ("temperature", "°C"), "C": ("temperature", "°C"),
    "s": ("duration", "s"), "ms": ("duration", "ms"), "min": ("duration", "min"), "h": ("duration", "h"),
    "rpm": (None, "rpm"), "r/min": (None, "rpm"),
}
STATE_MAX = 255  # Home Assistant refuses a longer state
_SLUG = re.compile(r"[^a-z0-9]+")


def slug(text: str) -> str:
    """`Output frequency` -> `output_frequency`, `holding[8448]` -> `holding_8448` (a topic level, an id);
    "%" is "pct" (`Output frequency (% of Cn-02)` -> `output_frequency_pct_of_cn_02`)."""
    return _SLUG.sub("_", str(text).lower().replace("%", " pct ")).strip("_") or "_"


def node_id(prefix: str, link: str, unit: int) -> str:
    return slug(f"sniffer_{prefix}_{link}_u{unit}")


def availability(prefix: str) -> str:
    return f"{prefix}/status"


def device(prefix: str, link: str, unit: int, model: str, model_name: str | None) -> dict:
    title = model_name or model
    d = {"identifiers": [node_id(prefix, link, unit)], "name": f"{title} unit {unit}" +
         ("" if link == "default" else f" ({link})"), "model": title, "model_id": model,
         "manufacturer": "rs485-sniffer (passive)", "sw_version": __version__}
    if link != "default":  # Home Assistant wants a string or nothing
        d["suggested_area"] = link
    return d


def discovery(spec, link: str, unit: int, model: str, model_name: str | None, state_topic: str,
              point: dict, shared: bool = False) -> tuple[str, bytes]:
    """(topic, payload) of the retained config that makes `point`'s register a Home Assistant sensor
    (`shared`: the model gives its name to several registers: the name says which)."""
    node = node_id(spec.prefix, link, unit)
    obj = state_topic.rsplit("/", 1)[1]
    name = point.get("name") or obj
    cfg = {
        "name": f"{name} (register {point.get('address')})" if shared else name,
        "unique_id": f"{node}_{obj}", "object_id": f"{node}_{obj}",
        "state_topic": state_topic, "availability_topic": availability(spec.prefix),
        "json_attributes_topic": state_topic, "device": device(spec.prefix, link, unit, model, model_name),
    }
    if point.get("text") is not None:
        cfg["value_template"] = "{{ value_json.text[:%d] }}" % STATE_MAX
        cfg["icon"] = "mdi:alert-circle-outline" if "fault" in str(point.get("name")).lower() else "mdi:text"
    else:
        cfg["value_template"] = "{{ value_json.value }}"
        unit_text = point.get("unit")
        if unit_text:
            cls, ha_unit = DEVICE_CLASS.get(unit_text, (None, unit_text))
            cfg["unit_of_measurement"] = ha_unit
            if cls:
                cfg["device_class"] = cls
        cfg["state_class"] = "measurement"
    return f"{spec.ha_prefix}/sensor/{node}/{obj}/config", orjson.dumps(cfg)


def health_discovery(spec, link: str, unit: int, model: str, model_name: str | None,
                     health_topic: str) -> tuple[str, bytes]:
    """(topic, payload) of a sensor for the unit's median response latency (its counts as attributes)."""
    node = node_id(spec.prefix, link, unit)
    cfg = {"name": "Response latency (median)", "unique_id": f"{node}_health", "object_id": f"{node}_health",
           "state_topic": health_topic, "availability_topic": availability(spec.prefix),
           "value_template": "{{ value_json.latency_ms.median }}", "unit_of_measurement": "ms",
           "device_class": "duration", "state_class": "measurement", "json_attributes_topic": health_topic,
           "entity_category": "diagnostic", "device": device(spec.prefix, link, unit, model, model_name)}
    return f"{spec.ha_prefix}/sensor/{node}/health/config", orjson.dumps(cfg)


__all__ = ["DEVICE_CLASS", "availability", "discovery", "health_discovery", "node_id", "slug"]
