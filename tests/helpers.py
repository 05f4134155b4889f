"""Small shared helpers for tests: run events through the real pipeline."""

from __future__ import annotations

import subprocess
import sys

from decoders.registry import default_registry
from sniffer.events import CaptureInfo, Chunk
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline


def fr(hex_body: str) -> str:
    """A frame's hex with its CRC appended."""
    from sniffer.framing.crc import crc_bytes

    b = bytes.fromhex(hex_body)
    return (b + crc_bytes(b)).hex()


def run_events(events, line: LineSettings, devices=None, info: CaptureInfo | None = None, **kw):
    info = info or CaptureInfo(baud=line.baud, parity=line.parity, stopbits=line.stopbits)
    p = Pipeline(info, line, default_registry(devices), **kw)
    out = []
    for ev in events:
        out += p.feed(ev)
    out += p.finish()
    return out


def bursts(frames_hex: list[str], line: LineSettings, gap_chars: float = 5.0, t0: int = 0) -> list[Chunk]:
    """Each hex string as back-to-back bytes with per-byte times, `gap_chars` of silence between."""
    out = []
    t = t0
    for h in frames_hex:
        data = bytes.fromhex(h)
        times = tuple(t + i * line.char_ns for i in range(len(data)))
        out.append(Chunk(t, data, times))
        t = times[-1] + line.char_ns + int(gap_chars * line.char_ns)
    return out


class ListSink:
    """Collects JSONL records (as the JSONL sink would write them) and raw events."""

    def __init__(self) -> None:
        self.records: list[dict] = []
        self.events: list = []
        self.t0 = 0

    def start(self, info) -> None:
        self.t0 = info.t0_ns

    def raw(self, event) -> None:
        self.events.append(event)

    def frame(self, f) -> None:
        from sniffer.formats.records import frame_record

        self.records.append(frame_record(f, self.t0))

    def close(self) -> None:
        pass


_SIMULATED: dict = {}


def simulate_and_decode(name: str, seconds: float, adapter: str = "wire", seed: int = 1,
                        devices=None, protocol=None):
    """(scenario, wire frames sent, frames decoded) for a simulated scenario; cached per arguments."""
    from sniffer.simulator import get_scenario, simulate, usb_chunks, wire_chunks

    key = (name, seconds, adapter, seed, tuple(sorted((devices or {}).items())), protocol)
    if key not in _SIMULATED:
        sc = get_scenario(name)
        sent = list(simulate(sc, sc.line, seconds, seed))
        chunks = wire_chunks(sent) if adapter == "wire" else usb_chunks(sent, seed=seed)
        got = run_events(chunks, sc.line, devices=devices or sc.devices, protocol=protocol or sc.protocol)
        _SIMULATED[key] = (sc, sent, got)
    return _SIMULATED[key]


_FILES: dict = {}


def simulated(factory, name: str, *flags: str):
    """`sniffer simulate FLAGS --out DIR/NAME` (a folder with --rotate), made once per test session; its path.
    `factory` is pytest's tmp_path_factory."""
    from sniffer.cli import main

    key = (name, flags)
    if key not in _FILES:
        path = factory.mktemp("sim") / name
        assert main(["simulate", *flags, "--out", str(path)]) == 0
        _FILES[key] = path
    return _FILES[key]


def run_sniffer(*args, timeout=120) -> subprocess.CompletedProcess:
    """`python -m sniffer ARGS` as a user runs it, output captured."""
    return subprocess.run([sys.executable, "-m", "sniffer", *args], capture_output=True, text=True, timeout=timeout)


def demo_records(tmp_path, scenario: str, seconds: float = 2) -> tuple[list[dict], str]:
    """`sniffer demo --headless --format jsonl` of a scenario over a real pty: (JSONL records, MCAP path).

    Asserts what every demo must do: exit 0, write nothing to the bus, decode more than a few frames."""
    import json

    out = str(tmp_path / "demo.mcap")
    r = run_sniffer("demo", "--scenario", scenario, "--duration", str(seconds), "--headless", "--format", "jsonl",
                    "--out", out)
    assert r.returncode == 0, r.stderr
    assert "sniffer wrote 0 bytes to the bus" in r.stderr
    recs = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(recs) > 10
    return recs, out



def decoded(path, spec=None):
    """(info, frames) of a capture file decoded through the session (frames as a list: small captures only)."""
    from sniffer.capture.session import decode_capture

    session = decode_capture(path, spec)
    frames = list(session)
    return session.info, frames


def export(capture, fmt: str, out, *flags: str) -> int:
    """`sniffer export CAPTURE --to FMT --out OUT FLAGS...` in this process: its exit code."""
    from sniffer.cli import main

    return main(["export", str(capture), "--to", fmt, "--out", str(out), *flags])


def read_mcap(path):
    """An MCAP read back with the mcap library: (summary, {metadata name: map}, {attachment name: attachment},
    [(channel, log time, the message's JSON decoded)] in file order)."""
    import json

    from mcap.reader import make_reader

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
        msgs = [(ch, m.log_time, json.loads(m.data)) for _s, ch, m in reader.iter_messages()]
    return summary, meta, attachments, msgs


class SimulatedLine:
    """A simulated line served on a pty (sniffer/simulator/uartpty.py: what a UART at the settings the reader sets
    receives), played in a thread, linked at DIR/NAME: `with SimulatedLine(tmp_path, "default") as line: line.path`."""

    def __init__(self, folder, scenario: str, line: str | None = None, name: str = "line0", seed: int = 5):
        import threading

        from sniffer.detect.candidates import setting
        from sniffer.simulator import get_scenario
        from sniffer.simulator.uartpty import PtyLine

        sc = get_scenario(scenario)
        b, f = (line or f"{sc.line.baud} {sc.line.databits}{sc.line.parity}{sc.line.stopbits}").split()
        self.pty = PtyLine(sc, setting(int(b), f), seed=seed)
        self.path = str(folder / name)
        self.pty.link(self.path)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.pty.play, args=(self.stop,), daemon=True)

    def __enter__(self) -> "SimulatedLine":
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join(5)
        self.pty.close()


def diagnose_source(source):
    """(findings, engine) of `sniffer diagnose` on a source (a simulated line), made and read in this process."""
    from sniffer.capture.session import Session
    from sniffer.capture.settings import CaptureSpec
    from sniffer.diagnose import Diagnosis

    session = Session(CaptureSpec.of(), source, [])
    session.open()
    engine = Diagnosis()
    engine.start_session(session)
    for f in session:
        engine.frame(f)
    return engine.findings(), engine


def frames_of(path) -> list[dict]:
    """The frame records of an MCAP file: its /frames, or, a compact file having none (a segment, a trigger
    window), the frames its /raw replays to alone, as `sniffer replay FILE` gives them."""
    from mcap.reader import make_reader

    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.formats.mcap.reader import open_mcap, read_frames

    with open(path, "rb") as fh:
        topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    if "/frames" in topics:
        return read_frames(str(path))
    info, events = open_mcap(str(path))
    out = ListSink()
    Session(CaptureSpec(), EventSource(info, events), [out]).run()
    return out.records


def window_holds(held: list, capture: list, start_t: float, end_t: float) -> bool:
    """A trigger window's frames (`held`: (t, ...) keys, from what it replays to) are the capture's (`capture`,
    the same keys in order) from its start to its end, and past its end at most the frames that finish in
    the reads it takes to end a frame begun (under a second), none skipped."""
    ours = [k for k in capture if start_t - 1e-9 <= k[0]]
    upto = sum(1 for k in ours if k[0] <= end_t + 1e-9)
    return len(held) >= upto and held == ours[: len(held)] and (not held or held[-1][0] <= end_t + 1.0)
