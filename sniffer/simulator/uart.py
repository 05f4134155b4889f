"""A bit-level UART model: the line's level over time, and what a receiver at any settings makes of it.

    wire = Wire(LineSettings(19200, "E", 1))          # the line, at its true settings
    wire.send(b"\\x01\\x03", [t0, t0 + char_ns])         # bytes at their start-bit times
    rx = Receiver(LineSettings(9600, "N", 1))          # a UART set to something else
    rx.receive(wire, until_ns)                         # -> [RxChar(t_ns, t_end_ns, value, error)]

The transmitter sends a start bit (0), the data bits LSB first, the parity bit
(even: the ones of data + parity are even) and the stop bits (1); the idle line
is 1.  The receiver works as a 16550-style UART does: it waits for a falling
edge, checks the start bit in its middle (a glitch shorter than half a bit is
no start), samples each following bit in its middle at its own baud rate, and
checks the parity bit and the *first* stop bit only (so a receiver set to 2 stop
bits takes 1-stop traffic without error, and the other way round).  Errors:

* "parity": the parity bit does not match (only when the receiver has parity);
* "framing": the stop bit was sampled as 0;
* "break": the line was low for the whole character, stop bit included (one
  0x00 with a break; the receiver then waits for the line to go high).

After a character the receiver looks for the next falling edge from its stop
sample on (`resync="edge"`), so after a framing error it waits for the line to
go high first.  Some UARTs instead take a low stop sample as the next start bit
(the 16550 datasheet's resynchronisation, `resync="16550"`); both are modelled
because a receiver set to the wrong character length decodes differently after
a framing error on each.  Times are integer ns; sans-I/O and deterministic.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from sniffer.line import LineSettings

RESYNC = ("edge", "16550")


def char_bits(value: int, line: LineSettings) -> list[int]:
    """The levels of one character on the wire, start bit to last stop bit."""
    data = [(value >> i) & 1 for i in range(line.databits)]
    bits = [0, *data]
    if line.parity != "N":
        ones = sum(data)
        bits.append(ones & 1 if line.parity == "E" else 1 - (ones & 1))
    return bits + [1] * line.stopbits


@dataclass(frozen=True, slots=True)
class RxChar:
    t_ns: int  # the falling edge the receiver took as its start bit
    t_end_ns: int  # its stop-bit sample: when the UART hands the character over
    value: int
    error: str = ""  # "", "parity", "framing" or "break"


class Wire:
    """The level of a line over time: idle high, then the transitions of what was sent.

    Transitions alternate (high -> low at even positions), so a level is the
    parity of the number of transitions up to a time.  `forget(t)` drops those
    before t that no one will look at again (a long-running line stays small).
    """

    def __init__(self, line: LineSettings) -> None:
        self.line = line
        self.bit_ns = 1e9 / line.baud
        self.times: list[int] = []
        self._dropped = 0  # transitions forgotten: keeps the parity of positions
        self._level = 1  # level after the last transition
        self.end_ns = 0  # the line is known up to here (then idle)

    def send(self, data: bytes, byte_t_ns: Sequence[int]) -> None:
        """Characters starting at the given times (increasing, after everything sent before)."""
        line, bit = self.line, self.bit_ns
        times, level = self.times, self._level
        for value, t0 in zip(data, byte_t_ns):
            for k, b in enumerate(char_bits(value, line)):
                if b != level:
                    times.append(t0 + round(k * bit))
                    level = b
            self.end_ns = t0 + round(line.bits_per_char * bit)
        self._level = level

    def hold_low(self, t0: int, t1: int) -> None:
        """A break: the line held low from t0 to t1 (after everything sent before)."""
        if self._level == 1:
            self.times += [t0, t1]
        self.end_ns = t1

    def level(self, t: int) -> int:
        """The level at time t (a transition at exactly t has happened)."""
        return 1 - ((bisect_right(self.times, t) + self._dropped) & 1)

    def next_fall(self, t: int) -> int | None:
        """The first high -> low transition at or after t, or None if none is known yet."""
        i = bisect_left(self.times, t)
        if (i + self._dropped) & 1:  # position i goes low -> high: the next one falls
            i += 1
        return self.times[i] if i < len(self.times) else None

    def rises_between(self, a: int, b: int) -> bool:
        """Does the line go high anywhere in (a, b]?"""
        i, j = bisect_right(self.times, a), bisect_right(self.times, b)
        return any((k + self._dropped) & 1 for k in range(i, j))

    def forget(self, t: int) -> None:
        k = bisect_left(self.times, t)
        if k:
            del self.times[:k]
            self._dropped += k


class Receiver:
    """A UART at `line` settings reading a Wire (see the module doc)."""

    def __init__(self, line: LineSettings, start_ns: int = 0, resync: str = "edge") -> None:
        if resync not in RESYNC:
            raise ValueError(f"resync must be one of {RESYNC}")
        self.line = line
        self.bit_ns = 1e9 / line.baud
        self.resync = resync
        self.hunt_ns = start_ns  # looks for a start bit from here on
        self._start: int | None = None  # a low stop sample taken as the next start bit (16550)

    @property
    def horizon_ns(self) -> int:
        """The earliest time the receiver will still look at (Wire.forget before it is safe)."""
        return self.hunt_ns if self._start is None else min(self.hunt_ns, self._start)

    def receive(self, wire: Wire, until_ns: int) -> list[RxChar]:
        """The characters whose stop sample falls at or before `until_ns`; the wire must be known up
        to there (what was sent up to it has been sent, and it is idle after `wire.end_ns`)."""
        out: list[RxChar] = []
        line, bit = self.line, self.bit_ns
        nd, np_ = line.databits, int(line.parity != "N")
        while True:
            te = self._start
            if te is None:
                te = wire.next_fall(self.hunt_ns)
                if te is None:
                    break
            stop_at = te + round((1.5 + nd + np_) * bit)
            if stop_at > until_ns:
                break
            self._start = None
            if wire.level(te + round(bit / 2)):  # not low in the middle of the start bit: a glitch
                self.hunt_ns = te + round(bit / 2)
                continue
            value = 0
            for i in range(nd):
                value |= wire.level(te + round((1.5 + i) * bit)) << i
            error = ""
            if np_:
                p = wire.level(te + round((1.5 + nd) * bit))
                ones = bin(value).count("1") + p
                if ones & 1 != (0 if line.parity == "E" else 1):
                    error = "parity"
            if not wire.level(stop_at):
                error = "framing" if wire.rises_between(te, stop_at) else "break"
            out.append(RxChar(te, stop_at, value, error))
            self.hunt_ns = stop_at
            if error == "framing" and self.resync == "16550":
                self._start = stop_at - round(bit / 2)  # the low stop bit is taken for the next start bit
        return out
