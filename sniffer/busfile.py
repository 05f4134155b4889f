"""Bus file: the serial settings, unit -> model map and timeouts of one line, in TOML.

    [serial]
    baud = 19200
    parity = "E"
    stopbits = 1

    [units]          # unit = model id
    1 = "a510"
    2 = "tds-v8"

    [timeouts_ms]    # optional, per unit
    1 = 250
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .tomlfile import read_toml


class BusFileError(ValueError):
    pass


@dataclass
class BusFile:
    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    protocol: str | None = None
    devices: dict[int, str] = field(default_factory=dict)
    timeouts_ms: dict[int, float] = field(default_factory=dict)


def load_bus_file(path: str) -> BusFile:
    doc = read_toml(path, BusFileError)
    bus = BusFile()
    serial = doc.get("serial", {})
    bus.baud = serial.get("baud")
    bus.parity = serial.get("parity")
    bus.stopbits = serial.get("stopbits")
    bus.protocol = serial.get("protocol")
    try:
        bus.devices = {int(k): str(v) for k, v in doc.get("units", {}).items()}
        bus.timeouts_ms = {int(k): float(v) for k, v in doc.get("timeouts_ms", {}).items()}
    except (TypeError, ValueError):
        raise BusFileError(f"{path}: [units] and [timeouts_ms] keys must be unit numbers") from None
    return bus
