"""Write synthetic sigrok session files (.sr) for tests: UART lines and a driver-enable line, sample-exact.

    t = Trace(1_000_000, ["RX", "TX", "DE"], idle={"DE": 0})
    end = t.uart("RX", 1000, bytes.fromhex("010300000001840a"), 9600, "E", 1)
    t.set("DE", end + 2000, 1)
    ...
    t.write(tmp_path / "line.sr")

The format is what libsigrok's srzip output writes: a zip of `version` ("2"),
`metadata` (INI: samplerate, unitsize, probeN=name) and the samples split into
`logic-1-1`, `logic-1-2`, ... (one byte per sample for up to 8 channels, bit
N-1 = probeN).  Bit edges fall on sample `start + round(k * rate / baud)`, so
each byte's start sample is exactly the `start` given.
"""

from __future__ import annotations

import zipfile
from pathlib import Path


def bit_edge(start: int, k: int, rate: int, baud: int) -> int:
    """Sample of the k-th bit boundary of a character starting at `start`."""
    return start + (2 * k * rate + baud) // (2 * baud)


def char_bits(value: int, parity: str = "N", stopbits: int = 1, databits: int = 8, *,
              bad_parity: bool = False, bad_stop: bool = False) -> list[int]:
    """The line levels of one character, start bit first (1 = idle/mark)."""
    data = [(value >> i) & 1 for i in range(databits)]
    bits = [0, *data]
    if parity != "N":
        p = sum(data) % 2 if parity == "E" else 1 - sum(data) % 2
        bits.append(p ^ 1 if bad_parity else p)
    bits += [0 if bad_stop else 1] + [1] * (stopbits - 1)
    return bits


class Trace:
    """Logic channels as level changes; `write` renders the samples into a .sr file."""

    def __init__(self, samplerate: int, channels: list[str], idle: dict[str, int] | None = None) -> None:
        self.rate = samplerate
        self.channels = list(channels)
        idle = idle or {}
        # UART lines idle high (mark); give a driver-enable line idle={"DE": 0}
        self.changes: dict[str, list[tuple[int, int]]] = {c: [(0, idle.get(c, 1))] for c in channels}
        self.end = 0

    def set(self, channel: str, sample: int, level: int) -> None:
        """`channel` is at `level` from `sample` on (later calls for later samples)."""
        self.changes[channel].append((sample, level))
        self.end = max(self.end, sample)

    def level_at(self, channel: str, sample: int) -> int:
        level = 0
        for s, v in self.changes[channel]:
            if s > sample:
                break
            level = v
        return level

    def uart(self, channel: str, start: int, data: bytes, baud: int, parity: str = "N", stopbits: int = 1, *,
             invert: bool = False, gap_bits: float = 0.0, bad_parity=(), bad_stop=(), databits: int = 8) -> int:
        """Send `data` from sample `start`, characters `gap_bits` apart (idle between them); bytes whose index
        is in bad_parity / bad_stop get a wrong parity bit / a 0 stop bit.  Returns the sample after the last
        stop bit (the line idle)."""
        t = start
        for i, value in enumerate(data):
            bits = char_bits(value, parity, stopbits, databits, bad_parity=i in bad_parity, bad_stop=i in bad_stop)
            for k, b in enumerate(bits):
                self.set(channel, bit_edge(t, k, self.rate, baud), b ^ invert)
            end = bit_edge(t, len(bits), self.rate, baud)
            self.set(channel, end, 1 ^ invert)
            t = end + round(gap_bits * self.rate / baud)
        return end

    def samples(self, end: int | None = None) -> bytes:
        """One byte per sample (bit i = channel i), from sample 0 up to `end` (default: a little after the last
        change)."""
        n = end if end is not None else self.end + self.rate // 1000 + 1
        points: dict[int, list[tuple[int, int]]] = {}
        for bit, ch in enumerate(self.channels):
            for s, v in self.changes[ch]:
                points.setdefault(s, []).append((bit, v))
        out = bytearray()
        value = 0
        at = 0
        for s in sorted(points):
            if s >= n:
                break
            out += bytes([value]) * (s - at)
            for bit, v in points[s]:
                value = value | (1 << bit) if v else value & ~(1 << bit)
            at = s
        out += bytes([value]) * (n - at)
        return bytes(out)

    def write(self, path: str | Path, end: int | None = None, member_size: int = 1 << 18) -> Path:
        if len(self.channels) > 8:
            raise ValueError("srgen writes up to 8 channels (one byte per sample)")
        data = self.samples(end)
        return write_sr(path, self.rate, self.channels, data, 1, member_size)


def rate_text(hz: int) -> str:
    for scale, unit in ((1_000_000_000, "GHz"), (1_000_000, "MHz"), (1_000, "kHz")):
        if hz % scale == 0:
            return f"{hz // scale} {unit}"
    return f"{hz} Hz"


def write_sr(path: str | Path, samplerate: int, channels: list[str], samples: bytes, unitsize: int = 1,
             member_size: int = 1 << 18) -> Path:
    """A .sr file of raw `samples` (`unitsize` bytes each), split into logic-1-N members of member_size bytes."""
    path = Path(path)
    meta = ["[global]", "sigrok version=0.5.2", "", "[device 1]", "capturefile=logic-1",
            f"total probes={len(channels)}", f"samplerate={rate_text(samplerate)}", "total analog=0"]
    meta += [f"probe{i + 1}={name}" for i, name in enumerate(channels)]
    meta += [f"unitsize={unitsize}", ""]
    member_size -= member_size % unitsize
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("version", "2")
        z.writestr("metadata", "\n".join(meta))
        for n, off in enumerate(range(0, len(samples), member_size), 1):
            z.writestr(f"logic-1-{n}", samples[off:off + member_size])
    return path


def edges(trace: Trace, channel: str) -> list[tuple[int, int]]:
    """The channel's edges [(sample, level after)], as a logic analyzer sees them (first: the level at 0)."""
    levels: dict[int, int] = {}
    for s, v in trace.changes[channel]:
        levels[s] = v  # a later change at the same sample wins, as in samples()
    out: list[tuple[int, int]] = []
    for s in sorted(levels):
        if not out or out[-1][1] != levels[s]:
            out.append((s, levels[s]))
    return out
