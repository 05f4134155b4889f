"""sigrok-cli's UART decoder output -> per-byte Chunks (sans-I/O: lines in, events out).

sigrok-cli runs at log level 4 with `--protocol-decoder-samplenum`, so every
annotation is one line naming its samples, decoder instance and class:

    31127-31180 uart-1: tx-start: "Start bit" "Start" "S"
    31179-31597 uart-1: tx-data: "01"
    31648-31701 uart-1: tx-parity-ok: "Stop bit" "Stop" "T"     (sigrok 0.5 files the stop bit there)
    0-13118 counter-1: edge_count: "1"                           (driver enable rose at sample 13118)
    21220-21220 counter-1: word_reset: "Word reset" ...          (and fell at 21220)

One `uart` instance decodes RX and TX (its annotations come in sample order);
a byte is complete at its "Stop bit", with a parity error ("Parity error") or
a framing error ("Frame error" before the stop bit) as its flag.  Its start
sample (the start bit's falling edge) is the start-bit annotation's first
sample corrected by how the decoder centres it (`start_shift`).  Times are
integer ns from sample numbers (rounded half up: exact at rates dividing
1 GHz).

The driver-enable line (--de) is watched by a `counter` decoder that runs
before the UART's, counting rising edges on it and "resetting" on its falling
edges (one decoder object: fewer of them keep libsigrokdecode 0.5.3's refcount
bug from aborting sigrok-cli at exit, sigrok_cli.FINALIZE_CRASH).  sigrok hands
each block of samples to its decoders in turn, so when a byte arrives, every
DE edge up to its stop bit has arrived.  A byte during which DE was high (at
its start, or rising before its stop bit) belongs to that DE window; the
window's bytes are held until its falling edge is known and then go out
carrying `de = (rise, fall)`
(sniffer.sources.driver_enable puts the turn-on/turn-off times on the frames), on the
wire `LogicSpec.de_channel` (their role: response).  A window held past
HOLD_BYTES or HOLD_S goes out without its fall (a DE stuck high).

`watermark(sample)`: the decoders have read every sample below it (sigrok's
"handled all samples" line, in sigrok_cli.py): every byte starting a character
before it has arrived, so a Tick says the line was silent until then.  The
lines are read up to the watermark's sample (each at the sample its decoder
printed it at: the lines of sigrok's next block wait), so the events are the
same however far stdout had been read when stderr's line came.  A Chunk
ends at a tick, a change of wire or DE window, or PER_BYTE_CHUNK bytes: where
sigrok's blocks of samples end, not when its lines happened to be read.
"""

from __future__ import annotations

import bisect
import re
from collections import deque
from math import ceil, floor

from sniffer.events import FLAG_FRAMING, FLAG_PARITY, Chunk, Tick
from sniffer.line import LineSettings
from sniffer.formats.csvstream import PER_BYTE_CHUNK
from sniffer.sources.logic_options import LogicSpec

_ANN = re.compile(rb'(\d+)-(\d+) ([\w.-]+): ([\w-]+): "([^"]*)"')
UART = "uart-1"
DE = b"counter-1"
HOLD_BYTES = PER_BYTE_CHUNK
HOLD_S = 1
MAX_PENDING = 200_000  # annotation lines waiting for a watermark (a sigrok-cli that prints none: read anyway)


def decoder_args(logic: LogicSpec, line: LineSettings) -> list[str]:
    """The -P / -A options that make sigrok-cli print what SigrokUart reads."""
    uart = f"uart:rx={logic.rx}"
    if logic.tx is not None:
        uart += f":tx={logic.tx}"
    parity = {"N": "none", "E": "even", "O": "odd"}[line.parity]
    uart += f":baudrate={line.baud}:parity={parity}:data_bits={line.databits}:format=hex"
    if logic.invert:
        uart += ":invert_rx=yes:invert_tx=yes"
    args: list[str] = []
    if logic.de is not None:
        args += ["-P", f"counter:data={logic.de}:reset={logic.de}:data_edge=rising:reset_edge=falling"]
    args += ["-P", uart]
    sides = ("rx", "tx") if logic.tx is not None else ("rx",)
    classes = ":".join(f"{s}-{c}" for s in sides for c in ("start", "data", "parity-ok", "parity-err", "warnings"))
    args += ["-A", f"uart={classes}" + (",counter=edge_count:word_reset" if logic.de is not None else ""),
             "--protocol-decoder-samplenum"]
    return args


class _Window:
    __slots__ = ("rise", "fall", "count")

    def __init__(self, rise: int | None) -> None:
        self.rise = rise  # sample; None: DE was high when the capture began
        self.fall: int | None = None
        self.count = 0


class SigrokUart:
    """Annotation lines -> Chunk and Tick events, in time order (see the module doc)."""

    def __init__(self, logic: LogicSpec, line: LineSettings, samplerate: int, de_initial: int = 0) -> None:
        self.logic = logic
        self.rate = samplerate
        bw = float(samplerate) / float(line.baud)  # as the decoder computes it
        self.start_shift = floor(bw / 2.0) - ceil((bw - 1) / 2.0)
        self.stop_offset = ceil((bw - 1) / 2.0 + (1 + line.databits + (line.parity != "N")) * bw)
        self.char_samples = ceil(line.bits_per_char * bw)
        self.char_ns = line.char_ns
        self.half_bit = ceil(bw / 2.0)  # a UART annotation ends this far past the sample it was printed at
        self.pending: deque = deque()  # (sample printed at, annotation) not read yet
        self.names = {"rx": logic.rx, "tx": logic.tx}
        self.de_line = logic.tx or logic.rx  # the slave's line: DE windows apply to its bytes
        self.de_channel = logic.de_channel if logic.de else None
        self.open: dict[str, list | None] = {"rx": None, "tx": None}  # [start sample, value, flags]
        self.out: list = []
        self.bytes = 0
        self.glitches = 0  # start bits that were not (sigrok: "Frame error" with no byte)
        # driver enable
        self.edges: list[tuple[int, int]] = []  # (sample, 1 rise / 0 fall), sorted, not yet folded in
        self.level0 = de_initial  # DE level before edges[0]
        self.rise0: int | None = None  # and the rise that set it, when it is high (None: high from the start)
        self.window: _Window | None = None
        self.held: list[tuple] = []  # (channel, start, value, flags, window) from the window's first byte on
        # the chunk being built
        self._ch: str | None = None
        self._de: tuple | None = None
        self._times: list[int] = []
        self._data = bytearray()
        self._flags: list[tuple[int, str]] = []
        self.last_t = -1  # ns of the last byte handed out (ticks come after it)
        self.tick_t = -1  # the last tick time noted
        self.ticks: deque[int] = deque()  # tick times waiting for their place

    # ------------------------------------------------------------------ input
    def feed(self, line: bytes) -> None:
        """One line of sigrok-cli's stdout.  It is read when a watermark passes the sample the decoder printed it
        at (or at the end, or when MAX_PENDING lines wait): the events never depend on how far stdout had been
        read when sigrok's stderr said a block was done."""
        m = _ANN.match(line)
        if m is None:
            return
        at = int(m.group(2)) - (self.half_bit if m.group(3) == b"uart-1" else 0)
        self.pending.append((at, m))
        if len(self.pending) > MAX_PENDING:
            self._read(self.pending.popleft()[1])

    def _read(self, m) -> None:
        inst, cls = m.group(3), m.group(4)
        if inst == b"uart-1":
            side = cls[:2].decode()
            what = cls[3:]
            cur = self.open[side]
            if what == b"start":
                self.open[side] = [int(m.group(1)) + self.start_shift, None, []]
            elif cur is None:
                if what == b"warnings":
                    self.glitches += 1
            elif what == b"data":
                cur[1] = int(m.group(5), 16)
            elif what == b"parity-err":
                cur[2].append(FLAG_PARITY)
            elif what == b"warnings":
                if cur[1] is not None:
                    cur[2].append(FLAG_FRAMING)
            elif what == b"parity-ok" and m.group(5) == b"Stop bit":
                self.open[side] = None
                if cur[1] is not None:
                    self._byte(self.names[side], cur[0], cur[1], cur[2])
        elif inst == DE:
            bisect.insort(self.edges, (int(m.group(2)), 1 if cls == b"edge_count" else 0))

    def watermark(self, sample: int) -> None:
        """Every sample below `sample` has been decoded."""
        pending = self.pending
        while pending and pending[0][0] < sample:
            self._read(pending.popleft()[1])
        w = self.window
        if w is not None:
            if w.fall is None:
                w.fall = self._fall_after(w.rise)
            if w.fall is not None and sample >= w.fall + self.char_samples:
                self._close_window(w.fall)
            elif self._held_too_long(sample):
                self._release_held(partial=True)
        t = self.ns(max(0, sample - self.char_samples - 1))  # no character to come starts before this
        if t > self.tick_t:
            self.ticks.append(t)
            self.tick_t = t
        if self.window is None:  # else held bytes come first: the ticks wait for their place between them
            self._fold(sample - self.char_samples - 1)
            self._ticks_before(None)

    def finish(self) -> None:
        """The end of the decode: held bytes go out (their window's fall, if it came)."""
        while self.pending:
            self._read(self.pending.popleft()[1])
        for side in ("rx", "tx"):
            cur = self.open[side]
            self.open[side] = None
            if cur is not None and cur[1] is not None:  # the capture ended inside its stop bit
                self._byte(self.names[side], cur[0], cur[1], cur[2])
        w = self.window
        if w is not None:
            self._close_window(w.fall if w.fall is not None else self._fall_after(w.rise))
        self._ticks_before(None)
        self._flush_chunk()

    def take(self) -> list:
        """The events decided so far.  The chunk being built waits for a tick, a change of wire or DE window, or
        the end: sigrok prints a line at a time, and a Chunk per byte would cost every stage a call per byte."""
        out, self.out = self.out, []
        return out

    def ns(self, sample: int) -> int:
        return (sample * 2_000_000_000 + self.rate) // (2 * self.rate)

    # --------------------------------------------------------------- bytes
    def _byte(self, channel: str, start: int, value: int, flags: list[str]) -> None:
        self.bytes += 1
        w = self.window
        if w is not None and w.fall is None:
            w.fall = self._fall_after(w.rise)  # the edges after an open window's rise are all still here
        window = None
        if self.de_channel is not None and channel == self.de_line:
            window = self._de_window(start, start + self.stop_offset)
        if w is not None and window is not w and (window is not None or (w.fall is not None and start >= w.fall)):
            self._close_window(w.fall)  # past its fall (or a new window while its fall is unknown: DE glitched)
        if window is not None:
            if self.window is None:
                self._flush_chunk()  # what came before the window is complete: out with it
                self.window = window
            window.count += 1
        if self.window is not None:
            rise = self.window.rise
            self._fold(start if rise is None else min(start, rise))
            self.held.append((channel, start, value, flags, window))
            if len(self.held) >= HOLD_BYTES:
                self._release_held(partial=True)
            return
        self._fold(start)
        self._add(channel, self.ns(start), value, flags, None)

    def _de_window(self, start: int, stop: int) -> _Window | None:
        """The DE window the byte [start, stop] was sent in (the open one if it is that), or None (DE low all
        through it)."""
        level = self.level0
        rise = self.rise0 if level else None
        i = 0
        edges = self.edges
        while i < len(edges) and edges[i][0] <= start:
            if edges[i][1]:
                rise = edges[i][0]
            level = edges[i][1]
            i += 1
        if not level:
            rise = next((s for s, v in edges[i:] if v and s <= stop), None)
            if rise is None:
                return None
        w = self.window
        return w if w is not None and w.rise == rise else _Window(rise)

    def _fold(self, upto: int) -> None:
        """Edges before `upto` are history: fold them into the level (and the rise) before the rest."""
        edges = self.edges
        n = 0
        while n < len(edges) and edges[n][0] < upto:
            self.level0 = edges[n][1]
            if edges[n][1]:
                self.rise0 = edges[n][0]
            n += 1
        if n:
            del edges[:n]

    def _fall_after(self, rise: int | None) -> int | None:
        for s, v in self.edges:
            if not v and (rise is None or s > rise):
                return s
        return None

    def _held_too_long(self, sample: int) -> bool:
        w = self.window
        first = self.held[0][1] if self.held else sample
        return sample - (w.rise if w.rise is not None else first) > HOLD_S * self.rate

    def _close_window(self, fall: int | None) -> None:
        w = self.window
        w.fall = fall
        self._release_held(partial=False)
        self.window = None
        if fall is not None:
            self._fold(fall)  # the fall itself stays: the level after it

    def _release_held(self, partial: bool) -> None:
        """The held bytes out: those of the window with de = (rise, fall) (fall None while partial)."""
        w = self.window
        de = (None if w.rise is None else self.ns(w.rise), None if partial or w.fall is None else self.ns(w.fall))
        for channel, start, value, flags, window in self.held:
            if window is not None:
                self._add(self.de_channel, self.ns(start), value, flags, de)
            else:
                self._add(channel, self.ns(start), value, flags, None)
        self.held = []
        if partial:
            self._flush_chunk()

    def _ticks_before(self, t: int | None) -> None:
        """The waiting ticks before time `t` (all: None) go out, each in its place in time: after the bytes before
        it (their chunk ends there), and only if the line was silent since the last byte.  A tick's place never
        depends on when sigrok's stderr line was read, so a file decodes to the same events however loaded the
        machine."""
        ticks = self.ticks
        while ticks and (t is None or ticks[0] < t):
            tick = ticks.popleft()
            if tick >= self.last_t + self.char_ns:  # the line was silent there (not inside a character)
                self._flush_chunk()
                self.out.append(Tick(tick))

    def _add(self, channel: str, t: int, value: int, flags: list[str], de) -> None:
        if self.ticks:
            self._ticks_before(t)
        if self._data and (channel != self._ch or de != self._de or len(self._data) >= PER_BYTE_CHUNK):
            self._flush_chunk()
        if not self._data:
            self._ch, self._de = channel, de
        for f in flags:
            self._flags.append((len(self._data), f))
        self._data.append(value)
        self._times.append(t)
        self.last_t = t

    def _flush_chunk(self) -> None:
        if not self._data:
            return
        self.out.append(Chunk(self._times[0], bytes(self._data), tuple(self._times), tuple(self._flags),
                              self._ch or "", de=self._de))
        self._data = bytearray()
        self._times = []
        self._flags = []
