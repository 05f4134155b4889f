"""Where decoded frames go: the sink interface (base.py).

Sinks live with what they feed: file formats in sniffer.formats (one `make_sink` by format name), the TUI's in
sniffer/tui/sink.py, the viewers' in sniffer/processes/publish_sink.py, triggers, MQTT and the status file in
their packages.
"""

from sniffer.sinks.base import Sink

__all__ = ["Sink"]
