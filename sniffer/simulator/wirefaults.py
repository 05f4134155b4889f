"""What the wire carries of a simulated line with faults (faults.py): collisions and reshaped characters.

    frames = wire_faults(bus_frames, scenario, line, seed)

After the bus (bus.py, with BusFaults' hooks) has said who sends what when, this stage puts the frames in
time order and lets the wire do the rest, read by a UART at the line's settings (uart.py):

* frames that overlap in time collide: the two drivers' levels AND-ed (a low wins), one burst as the
  UART reads it, and an answer to a request that collided is not sent (`collide`);
* driver_enable_late / driver_disable_early: the unit's answers with the line held idle (high, the bias
  holds it) before its transmitter turns on, or after it turns off (`_drivers`, `_reread`);
* bus_unbiased: after a transmission the released line floats, and now and then a receiver reads a stray
  character out of it (`_floating`).

Sans-I/O and deterministic for a seed.
"""

from __future__ import annotations

import dataclasses
import heapq
import random
from collections.abc import Iterable, Iterator

from sniffer.events import FLAG_FRAMING
from sniffer.line import LineSettings
from sniffer.simulator.wire import FAULT_NOISE, KIND_CORRUPTED, KIND_NOISE, KIND_REQUEST, WireFrame
from sniffer.simulator.received import FLAGS
from sniffer.simulator.scenario import Fault, Scenario
from sniffer.simulator.uart import Receiver, Wire


def wire_faults(frames: Iterable[WireFrame], sc: Scenario, line: LineSettings, seed: int) -> Iterator[WireFrame]:
    """The bus's frames as the wire carries them: in time order, overlapping ones collided, and the line
    faults of `sc.faults` applied to the bytes."""
    from sniffer.simulator.faults import find

    rng = random.Random(seed ^ 0x5EED)
    out = collide(frames, line)
    late_on, early_off = find(sc, "driver_enable_late"), find(sc, "driver_disable_early")
    if late_on or early_off:
        out = _drivers(out, line, rng, late_on, early_off)
    unbiased = find(sc, "bus_unbiased")
    if unbiased:
        out = _floating(out, line, rng, unbiased)
    return out


LAG_NS = 3_000_000_000  # frames come from the bus at most this far out of time order


def collide(frames: Iterable[WireFrame], line: LineSettings) -> Iterator[WireFrame]:
    """The frames in time order; frames that overlap become one frame as a UART at the line's settings reads
    the two drivers' levels AND-ed (a low wins), and an answer to a request that collided is not sent."""
    heap: list = []
    seq = 0
    lost: set[int] = set()  # exchanges whose request nobody heard
    for f in frames:
        heapq.heappush(heap, (f.t_ns, seq, f))
        seq += 1
        while heap and heap[0][2].t_end_ns + LAG_NS < f.t_ns:
            yield from _settle(heap, line, lost)
    while heap:
        yield from _settle(heap, line, lost)


def _settle(heap: list, line: LineSettings, lost: set[int]) -> Iterator[WireFrame]:
    group = [heapq.heappop(heap)[2]]
    end = group[0].t_end_ns
    while heap and heap[0][0] < end:
        g = heapq.heappop(heap)[2]
        group.append(g)
        end = max(end, g.t_end_ns)
    if len(group) == 1:
        f = group[0]
        if f.role in ("response", "exception") and f.txn in lost:
            return  # its request was not heard: no answer
        yield f
        return
    for g in group:
        if g.role == KIND_REQUEST:
            lost.add(g.txn)
    wire = Wire(line)
    levels = [_levels(g, line) for g in group]
    wire.times = _and(levels)
    wire._level = 1
    wire.end_ns = end
    chars = Receiver(line, start_ns=group[0].t_ns - 1, resync="16550").receive(wire, end + 2 * line.char_ns)
    if not chars:
        return
    yield WireFrame(chars[0].t_ns, chars[-1].t_end_ns, bytes(c.value for c in chars), tuple(c.t_ns for c in chars),
                    KIND_CORRUPTED, role="collision", fault="collision",
                    flags=tuple((i, FLAGS[c.error]) for i, c in enumerate(chars) if c.error))


def _levels(f: WireFrame, line: LineSettings) -> list[int]:
    w = Wire(line)
    w.send(f.raw, f.byte_t_ns)
    return w.times


def _and(transitions: list[list[int]]) -> list[int]:
    """The transitions of the AND of lines given by theirs (each idle high, alternating from a fall)."""
    events = sorted((t, k) for k, ts in enumerate(transitions) for t in ts)
    level = [1] * len(transitions)
    low = 0  # lines that are low
    out = []
    for t, k in events:
        level[k] ^= 1
        low += -1 if level[k] else 1
        now_low = low > 0
        was_low = len(out) % 2 == 1
        if now_low != was_low:
            if out and out[-1] == t:
                out.pop()  # a fall and a rise at the same instant cancel
            else:
                out.append(t)
    return out


def _drivers(frames: Iterable[WireFrame], line: LineSettings, rng: random.Random, late_on: tuple[Fault, ...],
             early_off: tuple[Fault, ...]) -> Iterator[WireFrame]:
    bit = 1e9 / line.baud
    for f in frames:
        answer = f.role in ("response", "exception") and f.fault != "collision" and f.unit is not None
        if answer and _hits(late_on, f, rng):
            # on after the start bit began: the line idles high until then (the bias holds it)
            f = _reread(f, line, hold_high=(f.t_ns - 1, f.t_ns + round(rng.uniform(1.0, 1.6) * bit)))
        if answer and _hits(early_off, f, rng):
            # off before the last character's end: the line goes back to idle high from there
            f = _reread(f, line, hold_high=(f.t_end_ns - round(rng.uniform(1.5, 4.0) * bit), f.t_end_ns + 1))
        yield f


def _hits(faults: tuple[Fault, ...], f: WireFrame, rng: random.Random) -> bool:
    """Whether a fault on the frame's unit reshapes this frame: in its span, on its severity's share of them."""
    from sniffer.simulator.faults import level, now

    fault = now(faults, f.t_ns, f.unit) if faults else None
    if fault is None:
        return False
    share = level(fault)
    return share >= 1.0 or rng.random() < share


def _reread(f: WireFrame, line: LineSettings, hold_high: tuple[int, int]) -> WireFrame:
    """The frame as a UART at the line's settings reads it when the line is held high (idle) in `hold_high`."""
    w = Wire(line)
    w.send(f.raw, f.byte_t_ns)
    a, b = hold_high
    times = [t for t in w.times if not a <= t < b]
    low_at_b = len([t for t in w.times if t < b]) % 2 == 1
    low_before_a = len([t for t in w.times if t < a]) % 2 == 1
    keep = [t for t in times if t < a]
    if low_before_a:
        keep.append(a)  # rises into the held-high stretch
    if low_at_b:
        keep.append(b)  # falls where the driver takes the line again
    keep += [t for t in times if t >= b]
    w.times = keep
    chars = Receiver(line, start_ns=f.t_ns - 1, resync="16550").receive(w, f.t_end_ns + 2 * line.char_ns)
    if not chars:
        return dataclasses.replace(f, raw=b"", byte_t_ns=())
    raw = bytes(c.value for c in chars)
    flags = tuple((i, FLAGS[c.error]) for i, c in enumerate(chars) if c.error)
    kind = f.kind if raw == f.raw else KIND_CORRUPTED
    return dataclasses.replace(f, t_ns=chars[0].t_ns, t_end_ns=max(f.t_end_ns, chars[-1].t_end_ns), raw=raw,
                               byte_t_ns=tuple(c.t_ns for c in chars), flags=flags, kind=kind)


_FLOAT_BYTES = ((0x00, FLAG_FRAMING), (0x00, FLAG_FRAMING), (0x00, FLAG_FRAMING), (0xFF, ""), (0xFF, ""),
                (0xFE, ""), (0xF0, ""), (0x80, FLAG_FRAMING))


def _floating(frames: Iterable[WireFrame], line: LineSettings, rng: random.Random,
              faults: tuple[Fault, ...]) -> Iterator[WireFrame]:
    """After a transmission the released line floats: now and then (the fault's severity: the chance after
    each transmission, in its span) a receiver reads a stray character out of it (a 00H with a framing
    error when it drifts low, FFH and the like from a short dip)."""
    from sniffer.simulator.faults import level, now

    char = line.char_ns
    prev = None
    for f in frames:
        if prev is not None:
            yield prev
            fault = now(faults, prev.t_end_ns) if prev.kind != KIND_NOISE else None
            if fault is not None and rng.random() < level(fault):
                t0 = prev.t_end_ns + int(rng.uniform(0.2, 0.9) * char)
                if t0 + 2 * char <= f.t_ns:  # room before the next transmission
                    value, flag = rng.choice(_FLOAT_BYTES)
                    yield WireFrame(t0, t0 + char, bytes((value,)), (t0,), KIND_NOISE, fault=FAULT_NOISE,
                                    flags=((0, flag),) if flag else ())
        prev = f
    if prev is not None:
        yield prev
