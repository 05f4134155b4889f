"""Deterministic replays for the TUI tests: decode a capture once, hand out its frames."""

from __future__ import annotations

import functools
from pathlib import Path

from decoders.registry import default_registry
from sniffer.line import LineSettings
from sniffer.pipeline import Pipeline
from sniffer.sources.replay import open_replay
from sniffer.tui.sink import TuiSink

SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"
SIM_CAPTURES = sorted(p.name for p in SIM.glob("*.mcap"))


@functools.cache
def _decode(name: str):
    info, events = open_replay(str(SIM / name) if "/" not in name else name)
    registry = default_registry(info.devices)
    sink = TuiSink()
    p = Pipeline(info, LineSettings(info.baud, info.parity or "N", info.stopbits or 1), registry, [sink],
                 protocol=info.protocol)
    for ev in events:
        p.feed(ev)
    p.finish()
    frames = sink.drain()
    return info, frames, registry


def replay_frames(name: str = "errors.mcap"):
    """(CaptureInfo, frames, registry) of a simulated capture (a name in captures/sim, or a path); frames are
    shared, do not mutate them."""
    return _decode(name)


def write_stress_capture(folder: Path, seconds: float = 1.0) -> str:
    """An MCAP of `sniffer simulate --scenario stress` (4 units polled back to back, one read of 125 registers
    0100H..017CH a cycle) in `folder`; a path for replay_frames / filled_sink."""
    from sniffer.cli import main

    path = str(folder / "stress.mcap")
    assert main(["simulate", "--scenario", "stress", "--duration", str(seconds), "--out", path]) == 0
    return path


def registry_shadow(registry) -> dict:
    """{(unit, table, address): raw} of the decoders' final register shadow (every unit's UnitState)."""
    return {(unit, table, a): v for unit, st in registry.states.items() for (table, a), v in st.snapshot().items()}


def filled_sink(name: str = "errors.mcap") -> TuiSink:
    """A sink as a finished replay leaves it: every frame pending, closed."""
    info, frames, _ = replay_frames(name)
    sink = TuiSink()
    sink.start(info)
    sink.frames(frames)
    sink.bytes_in = sum(len(f.raw) for f in frames)
    sink.close()
    return sink


def _word(adu: bytes, i: int) -> int:
    return adu[i] << 8 | adu[i + 1]


_TABLE = {1: "coil", 2: "discrete", 3: "holding", 4: "input", 5: "coil", 6: "holding", 15: "coil", 16: "holding"}


def touches(f, addr: int, table: str = "holding") -> bool:
    """Does a Modbus frame read or write register (or bit) `addr`?  A read request and a multiple write's
    echo by their address and quantity fields (PDU bytes 1-4), any frame by the addresses of its decoded
    points and of its register-shadow writes."""
    adu, fc = f.adu, f.function or 0
    if _TABLE.get(fc & 0x7F) != table:
        return False
    if f.crc_ok and len(adu) >= 6 and ((f.role == "request" and fc <= 4) or (f.role == "response" and fc in (15, 16))):
        if _word(adu, 2) <= addr < _word(adu, 2) + _word(adu, 4):
            return True
    if any(t == table and s <= addr < s + len(v) for t, s, v in f.writes):
        return True
    return any(p.get("address") == addr for p in f.points)
