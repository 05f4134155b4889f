"""Helpers for the TUI tests: deterministic replays (decode a capture once, hand out its frames), a live demo viewer."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import time
from pathlib import Path

from decoders.registry import default_registry
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.sources.files import open_replay
from sniffer.tui.store import FrameStore
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
    return info, frames, registry, sink.drain_reads()


def replay_frames(name: str = "errors.mcap"):
    """(CaptureInfo, frames, registry) of a simulated capture (a name in captures/sim, or a path); frames are
    shared, do not mutate them."""
    return _decode(name)[:3]


def replay_reads(name: str = "errors.mcap"):
    """The capture's reads as the TUI's sink marked them with their frames (sniffer.analysis.reads)."""
    return _decode(name)[3]


def frames_from_reads(reads) -> dict[int, bytes]:
    """Each frame's bytes put together from reads (sniffer.analysis.reads), byte by byte, by the frame each went to."""
    got: dict[int, bytearray] = {}
    for r in reads:
        for k, b in enumerate(r.data):
            got.setdefault(r.frame_at(k), bytearray()).append(b)
    return {i: bytes(v) for i, v in got.items()}


def store_of(name: str = "errors.mcap") -> FrameStore:
    """A FrameStore holding a simulated capture's frames."""
    info, frames, _ = replay_frames(name)
    s = FrameStore(info.t0_ns)
    s.add(frames)
    return s


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
    sink.reads(replay_reads(name))
    sink.bytes_in = sum(len(f.raw) for f in frames)
    sink.close()
    return sink


@contextlib.contextmanager
def demo_viewer(tmp_path, scenario: str, seconds: float, **spec):
    """`sniffer demo` with the TUI, as run_capture_tui runs it: the capture (the simulated bus on a pty,
    captured to an MCAP) a process of its own, the App attached to it over the capture's socket."""
    from sniffer.capture.session import CaptureSpec
    from sniffer.tui.run import CaptureViewer

    out = str(tmp_path / "d.mcap")
    with CaptureViewer(CaptureSpec(out=out, scenario=scenario, seed=1, duration_s=seconds, **spec), "demo",
                       f"demo {scenario}") as viewer:
        assert viewer.start(), "the demo capture did not start"
        yield viewer


def screen_text(app) -> str:
    """What the terminal shows now, as plain text lines (what a user reads, cut to the screen's size)."""
    import io

    from rich.console import Console

    w, h = app.size
    console = Console(width=w, height=h, file=io.StringIO(), force_terminal=True, color_system="truecolor",
                      record=True, legacy_windows=False, safe_box=False)
    console.print(app.screen._compositor.render_update(full=True))
    return console.export_text()


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


async def key_latency(app, pilot, key: str) -> float:
    """Seconds from posting a key to the moment the App has acted on it (the cursor moved).

    Pilot.press itself also waits for the screen to go idle, which a 15 Hz poll never
    quite lets happen; that wait is not what a user feels, so it is not counted.
    """
    fl = app.frame_list
    before = fl.cursor
    if key == "home" and before == 0 or key == "up" and before <= 0:
        fl.cursor = len(app.store.view) - 1
        await asyncio.sleep(0)
        before = fl.cursor
    t = time.perf_counter()
    task = asyncio.create_task(pilot.press(key))
    while fl.cursor == before and time.perf_counter() - t < 5:
        await asyncio.sleep(0.0005)
    dt = time.perf_counter() - t
    await task
    return dt
