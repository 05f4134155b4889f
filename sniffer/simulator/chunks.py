"""What a capture device would hand the sniffer for simulated traffic.

Two views of the same wire:

* `wire_chunks`: a logic analyzer, which knows every byte's start bit;
* `usb_chunks`: a USB-serial adapter (FTDI-like) read by a host program,
  which only knows when each read returned.  It glues frames that share a
  USB packet and splits a frame across packets, and that is exactly what
  the framer must survive, so the model follows the chip rather than an
  idealised "one read per frame".

FTDI model (AN232B-04): received bytes collect in a buffer; a USB packet of
at most `packet_size` bytes (2 of them modem status, so packet_size - 2 data
bytes) leaves when the buffer is full or when the latency timer expires.
The timer runs from the previous packet, not from the last byte: with an
empty buffer the chip still sends a status-only packet at each expiry.  So a
frame's bytes go out at the next tick of a free-running grid, wherever that
tick falls inside the frame.  The host then sees each packet after USB and
scheduling delays; if it wakes late, one read returns several packets.
"""

from __future__ import annotations

import random
from bisect import bisect_right
from collections.abc import Iterable, Iterator

from sniffer.events import Chunk
from sniffer.simulator.wire import WireFrame


def wire_chunks(frames: Iterable[WireFrame], channel: str = "") -> Iterator[Chunk]:
    """One per-byte-timed Chunk per frame, with the UART flags a logic analyzer would report."""
    for f in frames:
        yield Chunk(f.t_ns, f.raw, f.byte_t_ns, f.flags, channel)


def _usb_packets(frames, latency_ns: int, cap: int, rng: random.Random) -> Iterator[tuple[int, bytes]]:
    """(time the chip sends the packet, data bytes).

    A byte is in the chip's buffer once its stop bit ends.  The chip sends the buffer when it
    holds `cap` bytes, or when the latency timer (a grid of `latency_ns` from the last packet)
    runs out with bytes in it.  Taken a frame at a time: the bytes of a frame that arrive
    before the deadline and fit go in with one slice (bisect on their arrival times), as the
    byte-by-byte rule would put them (test_simulator checks both on random traffic).
    """
    anchor: int | None = None  # last packet time: the latency timer's grid starts here
    deadline = 0
    buf = bytearray()
    for f in frames:
        raw = f.raw
        n = len(raw)
        if not n:
            continue
        char = f.t_end_ns - f.byte_t_ns[-1]
        arr = [t + char for t in f.byte_t_ns]  # end of each byte's stop bit
        if anchor is None:
            anchor = arr[0] - rng.randrange(latency_ns)  # the timer's phase at power-up is arbitrary
        i = 0
        while i < n:
            a = arr[i]
            if buf and a > deadline:
                yield deadline, bytes(buf)
                buf.clear()
                anchor = deadline
            if not buf:
                deadline = anchor + ((a - anchor) // latency_ns + 1) * latency_ns
            # byte i goes in; so do the next ones that arrive by the deadline, up to the cap
            k = min(bisect_right(arr, deadline, i + 1, n), i + cap - len(buf))
            buf += raw[i:k]
            i = k
            if len(buf) >= cap:
                yield arr[k - 1], bytes(buf)
                buf.clear()
                anchor = arr[k - 1]
    if buf:
        yield deadline, bytes(buf)


def usb_chunks(
    frames: Iterable[WireFrame],
    latency_timer_ms: float = 16,
    packet_size: int = 64,
    seed: int = 0,
    host_delay_ms: tuple[float, float] = (0.1, 1.0),
    hiccup_prob: float = 0.02,
    hiccup_ms: tuple[float, float] = (2.0, 20.0),
    channel: str = "",
) -> Iterator[Chunk]:
    """Per-read Chunks (byte_t_ns None, t_ns = host time the read returned).

    host_delay_ms: USB transfer plus the reader thread waking up.  Now and
    then (hiccup_prob) the host is descheduled for longer, and the packets
    that arrived meanwhile come back as one read.
    """
    if packet_size < 3:
        raise ValueError("packet_size must leave room for data after the 2 status bytes")
    rng = random.Random(seed)
    latency_ns = max(1, int(latency_timer_ms * 1e6))
    packets = _usb_packets(frames, latency_ns, packet_size - 2, rng)
    last_t = 0
    pending: tuple[int, bytes] | None = None
    for sent, data in packets:
        arrived = sent + int(rng.uniform(*host_delay_ms) * 1e6)
        if pending is not None:
            if arrived <= pending[0]:  # landed while the host was still asleep: same read
                pending = (pending[0], pending[1] + data)
                continue
            yield Chunk(pending[0], pending[1], None, (), channel)
        wake = arrived
        if hiccup_prob and rng.random() < hiccup_prob:
            wake += int(rng.uniform(*hiccup_ms) * 1e6)
        last_t = max(last_t, wake)
        pending = (last_t, data)
    if pending is not None:
        yield Chunk(pending[0], pending[1], None, (), channel)
