"""Deterministic replays for the TUI tests: decode a capture once, hand out its frames."""

from __future__ import annotations

import functools
from pathlib import Path

from decoders.registry import default_registry
from sniffer.line import LineSettings
from sniffer.pipeline import Pipeline
from sniffer.sources.replay import open_replay
from sniffer.tui.model import FrameStore
from sniffer.tui.sink import TuiSink

SIM = Path(__file__).resolve().parent.parent / "captures" / "sim"
SIM_CAPTURES = sorted(p.name for p in SIM.glob("*.mcap"))


@functools.cache
def _decode(name: str):
    info, events = open_replay(str(SIM / name))
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
    """(CaptureInfo, frames, registry) of a simulated capture; frames are shared, do not mutate them."""
    return _decode(name)


def store_of(name: str = "errors.mcap") -> FrameStore:
    """A FrameStore holding a simulated capture's frames."""
    info, frames, _ = replay_frames(name)
    s = FrameStore(info.t0_ns)
    s.add(frames)
    return s


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


def screen_text(app) -> str:
    """What the terminal shows now, as plain text lines (what a user reads, cut to the screen's size)."""
    import io

    from rich.console import Console

    w, h = app.size
    console = Console(width=w, height=h, file=io.StringIO(), force_terminal=True, color_system="truecolor",
                      record=True, legacy_windows=False, safe_box=False)
    console.print(app.screen._compositor.render_update(full=True))
    return console.export_text()
