"""What a receiver at other settings makes of a simulated line (the bit-level model of uart.py).

    for burst in received(simulate(sc, sc.line, 10, 1), sc.line, LineSettings(9600, "N", 1)):
        burst.raw, burst.byte_t_ns, burst.flags      # the bytes a 9600 8N1 UART received

The line runs at its true settings; each RxBurst holds the characters a UART at
`rx` settings completed while one frame was on the line (up to the next frame's
start), with their start-edge times and the UART's error flags.  It has the
fields the capture-device views read (chunks.wire_chunks, chunks.usb_chunks), so
`sniffer simulate --receiver-baud B --receiver-parity P` records what a sniffer
set to B/P would have recorded.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from sniffer.events import FLAG_FRAMING, FLAG_PARITY
from sniffer.line import LineSettings
from sniffer.sources.parmrk import InputFlags, tty_bytes
from sniffer.simulator.wire import WireFrame
from sniffer.simulator.uart import Receiver, RxChar, Wire

GRID_NS = 1_000_000  # the latency timer of the adapter a pty line plays: 1 ms
# a UART flags a break as a framing error too (its stop bit was 0)
FLAGS = {"parity": FLAG_PARITY, "framing": FLAG_FRAMING, "break": FLAG_FRAMING}


@dataclass(frozen=True, slots=True)
class RxBurst:
    t_ns: int
    t_end_ns: int
    raw: bytes
    byte_t_ns: tuple[int, ...]
    flags: tuple[tuple[int, str], ...] = ()


def burst_of(chars: list[RxChar]) -> RxBurst:
    return RxBurst(chars[0].t_ns, chars[-1].t_end_ns, bytes(c.value for c in chars), tuple(c.t_ns for c in chars),
                   tuple((i, FLAGS[c.error]) for i, c in enumerate(chars) if c.error))


def tail_ns(rx: LineSettings) -> int:
    """Long enough after the line's last edge for a receiver at `rx` to finish what it started."""
    return round(2 * rx.bits_per_char * 1e9 / rx.baud)


def received_chars(frames: Iterable[WireFrame], line: LineSettings, rx: LineSettings,
                   resync: str = "edge") -> Iterator[list[RxChar]]:
    """The characters a UART at `rx` completes while each frame of `frames` (sent at `line`) is on the
    line, up to the next frame's start (lists may be empty)."""
    wire = Wire(line)
    receiver = Receiver(rx, resync=resync)
    for f in frames:
        yield receiver.receive(wire, f.t_ns - 1)  # the line is idle until f starts
        wire.forget(receiver.horizon_ns)
        wire.send(f.raw, f.byte_t_ns)
    yield receiver.receive(wire, wire.end_ns + tail_ns(rx))


def received(frames: Iterable[WireFrame], line: LineSettings, rx: LineSettings,
             resync: str = "edge") -> Iterator[RxBurst]:
    """The bursts a UART at `rx` receives from `frames` sent at `line` (see the module doc)."""
    for chars in received_chars(frames, line, rx, resync):
        if chars:
            yield burst_of(chars)


def packets(chars: list[RxChar], grid_ns: int = GRID_NS) -> Iterator[tuple[int, list[RxChar]]]:
    """(time, characters): what a USB adapter whose latency timer is `grid_ns` sends when, of
    characters in time order (those completed within one period go at its end)."""
    i = 0
    while i < len(chars):
        due = (chars[i].t_end_ns // grid_ns + 1) * grid_ns
        j = i
        while j < len(chars) and chars[j].t_end_ns < due:
            j += 1
        yield due, chars[i:j]
        i = j


def tty_reads(frames: Iterable[WireFrame], line: LineSettings, rx: LineSettings, flags: InputFlags,
              resync: str = "edge", grid_ns: int = GRID_NS) -> Iterator[tuple[int, bytes]]:
    """(time, bytes) of the reads a program gets from a tty at `rx` with input `flags` (marks where
    asked for): what PtyLine (uartpty.py) writes to a pty, without a pty."""
    for chars in received_chars(frames, line, rx, resync):
        for due, group in packets(chars, grid_ns):
            yield due, tty_bytes(((c.value, c.error) for c in group), flags)


class LiveLine:
    """A line received by a UART whose settings may change at any time (a sniffer trying settings).
    Sans-I/O: `step(settings)` puts the next frame on the wire and gives the reads it causes;
    `retune(settings, t)` is the UART set to something else at bus time t, mid-frame or not.

        line = LiveLine(simulate(sc, sc.line, 60, 1), sc.line)
        while (t := line.next_t_ns) is not None:      # at bus time t, with the tty's settings:
            for due_ns, data in line.step(settings):   # write data at bus time due_ns
                ...                                    # (settings changed meanwhile: retune, write those)
    """

    def __init__(self, frames: Iterable[WireFrame], line: LineSettings, resync: str = "edge",
                 grid_ns: int = GRID_NS) -> None:
        self.wire = Wire(line)
        self.resync = resync
        self.grid_ns = grid_ns
        self.frames_sent = 0
        self.settings = None  # what the UART is set to
        self._frames = iter(frames)
        self._next = next(self._frames, None)
        self._receiver: Receiver | None = None
        self._until = 0  # the wire is known (sent, then idle) up to here

    @property
    def next_t_ns(self) -> int | None:
        """The start of the next frame (None: the line has said everything)."""
        return self._next.t_ns if self._next is not None else None

    @property
    def known_ns(self) -> int:
        """The wire is known (sent, then idle) up to here: the reads up to it are worked out."""
        return self._until

    def step(self, settings, keep_from_ns: int | None = None) -> list[tuple[int, bytes]]:
        """Send the next frame; (bus time, bytes) of the reads a tty set to `settings`
        (pty_settings.PortSettings) gets from it, up to the start of the frame after it.  A caller that
        steps ahead of time keeps the wire from `keep_from_ns` on, for a `retune` then."""
        f = self._next
        if f is None:
            return []
        if settings != self.settings or self._receiver is None:
            self.settings = settings
            self._receiver = Receiver(settings.line, start_ns=f.t_ns, resync=self.resync)
        horizon = self._receiver.horizon_ns
        self.wire.forget(horizon if keep_from_ns is None else min(horizon, keep_from_ns))
        self.wire.send(f.raw, f.byte_t_ns)
        self.frames_sent += 1
        self._next = next(self._frames, None)
        self._until = self._next.t_ns - 1 if self._next is not None else self.wire.end_ns + tail_ns(settings.line)
        return self._reads()

    def retune(self, settings, t_ns: int) -> list[tuple[int, bytes]]:
        """The UART set to `settings` at bus time t_ns: the reads it gets from then on, up to `known_ns`
        (they replace those `step` gave for after t_ns)."""
        self.settings = settings
        self._receiver = Receiver(settings.line, start_ns=t_ns, resync=self.resync)
        return self._reads()

    def _reads(self) -> list[tuple[int, bytes]]:
        chars = self._receiver.receive(self.wire, self._until)
        return [(due, tty_bytes(((c.value, c.error) for c in group), self.settings.flags))
                for due, group in packets(chars, self.grid_ns)]
