"""Simulated Modbus RTU / ASCII line: a PLC master, drive slaves, faults, capture devices.

    frames = simulate(get_scenario("errors"), LineSettings(9600, "E"), 10.0, seed=1)
    chunks = wire_chunks(frames)          # a logic analyzer's view
    chunks = usb_chunks(frames, seed=1)   # a USB adapter's view
    PtyBus().play(frames)                 # a live port for the real serial source
    received(frames, line, rx)            # what a UART at other settings receives (uart.py model)
    PtyLine(scenario, line).play()        # a pty line that delivers what the sniffer's settings receive

The generic drives keep a Delta-like layout (DriveMap); units named in a
scenario's `devices` are drives of a real model (profiles.py: TDS-V8, TECO
A510, Synplus SPL) that speak their manual's registers, faults and
exception codes.  Scenarios `pd-series` / `pd-series-ascii` put PD-series
inverters on the line instead (not Modbus: pd_master.py, pd_drive.py, from
the decoder's schema), with the protocol's > 50 ms quiet time before every
frame.  Everything but PtyBus is sans-I/O and deterministic for a
seed, so tests can compare the sniffer's output with the simulator's ground
truth.
"""

from __future__ import annotations

from sniffer import face
from sniffer.simulator.bus import (
    FAULT_BROADCAST_ANSWER, FAULT_CRC, FAULT_EXCEPTION, FAULT_NOISE, FAULT_TIMEOUT, KIND_BROADCAST, KIND_CORRUPTED,
    KIND_EXCEPTION, KIND_NOISE, KIND_REQUEST, KIND_RESPONSE, KINDS, WireFrame, simulate,
)
from sniffer.simulator.chunks import usb_chunks, wire_chunks
from sniffer.simulator.profiles import PROFILES, ModelProfile, get_model
from sniffer.simulator.scenario import SCENARIOS, DriveMap, PollSpec, Scenario, UnitSpec, get_scenario

__all__ = [
    "FAULT_BROADCAST_ANSWER", "FAULT_CRC", "FAULT_EXCEPTION", "FAULT_NOISE", "FAULT_TIMEOUT",
    "KIND_BROADCAST", "KIND_CORRUPTED", "KIND_EXCEPTION", "KIND_NOISE", "KIND_REQUEST",
    "KIND_RESPONSE", "KINDS", "PROFILES", "SCENARIOS", "DriveMap", "ModelProfile", "PlayStats", "PollSpec",
    "PtyBus", "Scenario", "UnitSpec", "WireFrame", "get_model", "get_scenario", "simulate", "usb_chunks",
    "wire_chunks",
]
# the pseudo-terminal bus needs termios: imported when used, so the rest simulates where there is none
__getattr__ = face(__name__, {"PlayStats": "sniffer.simulator.ptybus", "PtyBus": "sniffer.simulator.ptybus"})
