"""`sniffer detect` on a logic capture (.sr file) or a live analyzer (sigrok:DRIVER): measure, then decode.

1. Edges: sigrok-cli runs one `parallel` decoder over up to 8 channels (with
   no clock it prints the channels' levels at every change of any of them),
   reading the file (`-i FILE`) or `--samples N` of the analyzer; the first
   MAX_EDGES edges of each channel are kept (memory stays flat whatever the
   capture's length).
2. Measure (bitwidth.py): baud rate, polarity, parity and stop bits of every
   channel that toggles.
3. Verify: sigrok's UART decoder reads the channel at the settings measured
   (sources/sigrok_cli.py, the replay's path) and our framer and pairer read
   its bytes: UART errors, frames with a good CRC, request/response pairs.
A channel is settled when the measurement tells parity and stop bits and the
decode has no UART error and good frames.
"""

from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass

from sniffer.frame import CAN_REQ, CAN_RSP
from sniffer.line import LineSettings
from sniffer.events import CaptureError
from sniffer.orphans import external_ends_with_parent
from sniffer.sources.logic_options import LogicSpec
from sniffer.detect.bitwidth import Measurement, measure

MAX_EDGES = 200_000
MAX_CHANNELS = 8  # the parallel decoder's data lines
VERIFY_BYTES = 4000
_ITEM = re.compile(rb"(\d+)-(\d+) parallel-1: ([0-9a-fA-F]+)")


@dataclass
class Verified:
    bytes: int = 0
    uart_errors: int = 0
    frames: int = 0
    crc_ok: int = 0
    pairs: int = 0
    requests: int = 0  # frames whose structure only a request has
    responses: int = 0

    def describe(self) -> str:
        return (f"{self.bytes} bytes decoded: {self.uart_errors} UART errors, {self.crc_ok} of {self.frames} frames "
                f"with a good CRC/LRC, {self.pairs} request/response pairs")


def edge_args(channels: list[str]) -> list[str]:
    spec = ":".join(f"d{i}={ch}" for i, ch in enumerate(channels))
    return ["-P", f"parallel:{spec}", "-A", "parallel=items", "--protocol-decoder-samplenum"]


def collect_edges(acquire: list[str], channels: list[str], where: str) -> dict[str, list[tuple[int, int]]]:
    """{channel: [(sample, level after), ...]} in order, at most MAX_EDGES each (see the module doc)."""
    from sniffer.sources.sigrok_cli import FINALIZE_CRASH, sigrok_cli

    if not 1 <= len(channels) <= MAX_CHANNELS:
        raise CaptureError(f"{where}: {len(channels)} channels: give the one to measure (--rx CHANNEL); "
                           f"up to {MAX_CHANNELS} are measured at once")
    edges: dict[str, list[tuple[int, int]]] = {ch: [] for ch in channels}
    lists = [edges[ch] for ch in channels]
    proc = subprocess.Popen([sigrok_cli(), *acquire, *edge_args(channels)], stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=external_ends_with_parent())
    prev = None
    full = 0
    try:
        fd = proc.stdout.fileno()
        buf = b""
        while full < len(lists):
            data = os.read(fd, 1 << 16)
            if not data:
                break
            lines = (buf + data).split(b"\n")
            buf = lines.pop()
            for line in lines:
                m = _ITEM.match(line)
                if m is None:
                    continue
                value = int(m.group(3), 16)
                changed = -1 if prev is None else value ^ prev  # the first: every channel's level from here
                at = int(m.group(1))
                for i, lst in enumerate(lists):
                    if changed >> i & 1 and len(lst) < MAX_EDGES:
                        lst.append((at, value >> i & 1))
                        if len(lst) == MAX_EDGES:
                            full += 1
                prev = value
    finally:
        if proc.poll() is None:
            proc.terminate()
        _, err = proc.communicate()
    rc = proc.returncode
    if rc not in (0, -15) and FINALIZE_CRASH not in err and prev is None:
        why = [x for x in err.decode("utf-8", "replace").splitlines() if x.strip()]
        raise CaptureError(f"{where}: sigrok-cli failed (exit {rc}){': ' + why[-1] if why else ''}")
    return edges


def verify(source_of, m: Measurement) -> Verified:
    """Decode the channel at the measured settings (`source_of(LogicSpec)` gives the SigrokSource)."""
    from decoders.registry import default_registry

    from sniffer.capture.pipeline import Pipeline

    logic = LogicSpec(m.channel, invert=m.inverted, baud=m.baud, parity=m.parity, stopbits=m.stopbits,
                      databits=m.databits)
    line = LineSettings(m.baud, m.parity, m.stopbits, m.databits)
    src = source_of(logic)
    info = src.open()
    v = Verified()
    p = Pipeline(info, line, default_registry(default=protocol_of(m).default_model), protocol=protocol_of(m).name)
    frames = []
    try:
        for ev in src.events():
            if hasattr(ev, "data"):
                v.bytes += len(ev.data)
                v.uart_errors += len(ev.flags)
            frames += p.feed(ev)
            if v.bytes >= VERIFY_BYTES:
                break
    finally:
        src.close()
    frames += p.flush()
    v.frames = len(frames)
    v.crc_ok = sum(1 for f in frames if f.crc_ok)
    v.requests = sum(1 for f in frames if f.crc_ok and f.role_fits == CAN_REQ)
    v.responses = sum(1 for f in frames if f.crc_ok and f.role_fits == CAN_RSP)
    v.pairs = sum(1 for f in frames if f.role == "response" and f.pair is not None)
    return v


def protocol_of(m: Measurement):
    """The protocol a line of this format is read with: Modbus ASCII on 7 data bits, else RTU."""
    from sniffer.protocols import get

    return get("modbus-ascii" if m.databits == 7 else "modbus-rtu")


def judge(m: Measurement | None, v: Verified | None) -> str:
    """'settled', 'not told' (the measurement could not say parity or stop bits), 'errors', 'no frames' or
    'no UART'."""
    if m is None:
        return "no UART"
    if not m.settled:
        return "not told"
    if v is None or v.bytes == 0:
        return "no UART"
    if v.uart_errors:
        return "errors"
    return "settled" if v.crc_ok else "no frames"


@dataclass
class ChannelVerdict:
    channel: str
    measurement: Measurement | None
    verified: Verified | None
    verdict: str


def detect_logic(where: str, acquire: list[str], channels: list[str], samplerate: int,
                 source_of) -> list[ChannelVerdict]:
    """Measure every channel (`acquire`: sigrok-cli's input options), then decode each one that toggles at its
    settings (`source_of(LogicSpec)`: the SigrokSource that reads it again)."""
    edges = collect_edges(acquire, channels, where)
    out = []
    for ch in channels:
        m = measure(ch, edges[ch], samplerate)
        v = verify(source_of, m) if m is not None and m.settled else None
        out.append(ChannelVerdict(ch, m, v, judge(m, v)))
    return out


HEADER = ("channel", "baud", "format", "idle", "bit width", "chars", "verdict", "decoded at these settings")


def table(verdicts: list[ChannelVerdict]) -> list[str]:
    rows = [HEADER]
    for c in verdicts:
        m, v = c.measurement, c.verified
        if m is None:
            rows.append((c.channel, "-", "-", "-", "-", "-", c.verdict, "no UART traffic (fewer than 20 edges, "
                         "or no common bit width)"))
            continue
        votes = "; ".join(f"bit 9 {k}: {n}" for k, n in m.parity_votes.items())
        rows.append((c.channel, str(m.baud), m.fmt, "low (invert)" if m.inverted else "high",
                     f"{m.bit_samples:.2f} samples", str(m.chars), c.verdict, v.describe() if v is not None else votes))
    widths = [max(len(r[i]) for r in rows) for i in range(len(HEADER))]
    return ["  ".join(x.ljust(w) for x, w in zip(r, widths)).rstrip() for r in rows]


def summary(verdicts: list[ChannelVerdict], where: str) -> tuple[str, list[str], list[str]] | None:
    """(the line's settings, the channel flags and the serial flags that decode it) from the settled channels,
    or None."""
    ok = [c for c in verdicts if c.verdict == "settled"]
    if not ok:
        return None
    m = ok[0].measurement
    same = [c for c in ok if (c.measurement.baud, c.measurement.fmt, c.measurement.inverted) == (m.baud, m.fmt,
                                                                                                  m.inverted)]
    serial = ["--baud", str(m.baud), "--parity", m.parity, "--stopbits", str(m.stopbits)]
    if m.databits != 8:
        serial += ["--protocol", protocol_of(m).name]
    if len(same) >= 2:
        # the slave receives requests: the channel with more frames that can only be requests is --rx
        rx = max(same, key=lambda c: c.verified.requests - c.verified.responses)
        tx = next(c for c in same if c is not rx)
        flags = ["--rx", rx.channel, "--tx", tx.channel]
        on = f"on {rx.channel} (requests) and {tx.channel} (responses)"
    else:
        flags = ["--rx", ok[0].channel]
        on = f"on {ok[0].channel}"
    if m.inverted:
        flags.append("--invert")
    inv = ", idle low (inverted)" if m.inverted else ""
    return f"{m.baud} {m.fmt}{inv} {on}", flags, serial
