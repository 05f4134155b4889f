"""Passive RS-485 sniffer for PLC <-> drive links.

Pipeline: source -> framer -> pairer -> decoder registry -> sinks.
Every stage is sans-I/O; `sniffer.pipeline.Pipeline` drives them for live
capture, replay and tests alike.
"""

__version__ = "0.1.0"
