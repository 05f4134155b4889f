"""Read-only value bridge to MQTT / Home Assistant (`--mqtt URL`): see bridge.py for the topics.

options.py  the flags, checked once (MqttSpec)
bridge.py   frames -> messages, sans-I/O: confirmed values, health, events, rate limit, change-only
ha.py       Home Assistant discovery configs
client.py   the client's thread: bounded queue, reconnects, the retained state kept and republished
sink.py     the sink the session adds
"""

from sniffer.mqtt.options import MqttSpec

__all__ = ["MqttSpec"]
