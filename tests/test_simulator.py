"""The simulator is the sniffer's ground truth, so it gets tested like a product.

What matters: the same seed gives the same line, every frame is what its
label says (CRC valid unless deliberately damaged), timings follow the
scenario, the USB model glues and splits without losing bytes, the pty
carries bytes untouched, and the framer recovers the simulated frames.
"""

from __future__ import annotations

import os
import select
import struct
import threading
from bisect import bisect_right
from collections import Counter
from itertools import accumulate

import pytest

from sniffer.framing.crc import crc_bytes, crc_ok
from sniffer.events import Chunk
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings
from sniffer.framing.rtu_lengths import candidates
from sniffer.simulator import (
    FAULT_BROADCAST_ANSWER,
    FAULT_CRC,
    FAULT_TIMEOUT,
    KIND_BROADCAST,
    KIND_CORRUPTED,
    KIND_EXCEPTION,
    KIND_NOISE,
    KIND_REQUEST,
    KIND_RESPONSE,
    KINDS,
    SCENARIOS,
    PtyBus,
    WireFrame,
    get_scenario,
    simulate,
    usb_chunks,
    wire_chunks,
)

L9600 = LineSettings(9600, "E")
L115200 = LineSettings(115200, "N")
LINES = {"default": L9600, "errors": L9600, "fast": L115200, "stress": L115200}
MODELS = ["tds-v8", "a510", "a510-ascii", "spl", "spl-ascii"]  # real drive models (test_simulated_models.py)
LINES.update({name: get_scenario(name).line for name in MODELS})

_cache: dict = {}


def sim(name: str, line: LineSettings | None = None, duration: float = 20.0, seed: int = 1) -> list[WireFrame]:
    line = line or LINES[name]
    key = (name, line, duration, seed)
    if key not in _cache:
        _cache[key] = list(simulate(get_scenario(name), line, duration, seed))
    return _cache[key]


def test_registry_and_unknown_name():
    assert set(SCENARIOS) >= {"default", "errors", "fast", "stress", *MODELS}
    with pytest.raises(ValueError, match="unknown scenario"):
        get_scenario("nope")


def test_same_seed_same_line_other_seed_other_line():
    a = list(simulate(get_scenario("errors"), L9600, 5.0, seed=7))
    b = list(simulate(get_scenario("errors"), L9600, 5.0, seed=7))
    c = list(simulate(get_scenario("errors"), L9600, 5.0, seed=8))
    assert a == b
    assert [f.raw for f in a] != [f.raw for f in c]


@pytest.mark.parametrize("name", ["default", "errors", "fast", "stress", "tds-v8", "a510", "spl"])
def test_crc_valid_unless_damaged_and_lengths_fit_function(name):
    frames = sim(name)
    assert frames
    for f in frames:
        assert f.kind in KINDS
        if f.kind in (KIND_CORRUPTED, KIND_NOISE):
            if f.kind == KIND_CORRUPTED:
                assert not crc_ok(f.raw), f
            continue
        assert crc_ok(f.raw), f
        assert f.raw[0] == f.unit and f.raw[1] == f.function
        # the simulator must speak the same Modbus the framer's length table knows
        lengths = [n for n, _ in candidates(f.raw, 0, len(f.raw)) if type(n) is int]
        assert len(f.raw) in lengths, (f.raw.hex(" "), lengths)


@pytest.mark.parametrize("name", ["default", "errors", "fast", "stress", *MODELS])
def test_bytes_back_to_back_and_frames_never_overlap(name):
    line = LINES[name]
    sc = get_scenario(name)
    jitter = int(sc.byte_jitter_bits * 1e9 / line.baud)
    prev_end = 0
    for f in sim(name):
        assert f.t_ns == f.byte_t_ns[0] and len(f.byte_t_ns) == len(f.raw)
        assert f.t_end_ns == f.byte_t_ns[-1] + line.char_ns
        for a, b in zip(f.byte_t_ns, f.byte_t_ns[1:]):
            assert line.char_ns <= b - a <= line.char_ns + jitter
        assert f.t_ns > prev_end  # half duplex: one talker at a time
        prev_end = f.t_end_ns


@pytest.mark.parametrize("name", ["default", "fast", "errors"])
def test_turnaround_follows_each_units_configuration(name):
    line = LINES[name]
    sc = get_scenario(name)
    specs = {u.unit: u for u in sc.units}
    frames = sim(name)
    per_unit: dict[int, list[float]] = {}
    late = Counter()
    replies = Counter()
    for req, rsp in zip(frames, frames[1:]):
        if rsp.turnaround_ns is None or req.kind == KIND_BROADCAST:
            continue
        assert rsp.t_ns - req.t_end_ns == rsp.turnaround_ns  # the label matches the wire
        chars = rsp.turnaround_ns / line.char_ns
        spec = specs[rsp.unit]
        replies[rsp.unit] += 1
        if rsp.late:
            late[rsp.unit] += 1
            lo, hi = spec.slow_turnaround_chars
        else:
            lo, hi = spec.turnaround_chars
            per_unit.setdefault(rsp.unit, []).append(chars)
        assert lo - 0.01 <= chars <= hi + 0.01
    for unit, spec in specs.items():
        xs = per_unit[unit]
        lo, hi = spec.turnaround_chars
        assert len(xs) > 30
        assert min(xs) < lo + 0.15 * (hi - lo) and max(xs) > hi - 0.15 * (hi - lo)  # spread, not a constant
        if spec.slow_prob:
            assert 0.3 * spec.slow_prob < late[unit] / replies[unit] < 2.5 * spec.slow_prob
        else:
            assert late[unit] == 0
    # the point of the default timings: most replies come before t3.5 of silence
    short = sum(x * line.char_ns < line.t35_ns for xs in per_unit.values() for x in xs)
    assert short > 0.5 * sum(map(len, per_unit.values()))


def test_errors_scenario_produces_every_fault():
    frames = sim("errors")
    kinds = Counter(f.kind for f in frames)
    for k in KINDS:
        assert kinds[k] > 0, k
    codes = {f.exception_code for f in frames if f.kind == KIND_EXCEPTION}
    assert {0x01, 0x02, 0x06} <= codes
    damaged = Counter(f.role for f in frames if f.fault == FAULT_CRC)
    assert damaged[KIND_REQUEST] and (damaged[KIND_RESPONSE] + damaged[KIND_EXCEPTION])
    assert any(f.fault == FAULT_TIMEOUT and not f.answered for f in frames)
    # retries repeat the first attempt's bytes exactly
    firsts = {f.txn: f.raw for f in frames if f.role == KIND_REQUEST and f.attempt == 0 and f.kind == KIND_REQUEST}
    retries = [f for f in frames if f.role == KIND_REQUEST and f.attempt > 0 and f.kind == KIND_REQUEST]
    assert retries and all(f.raw == firsts[f.txn] for f in retries if f.txn in firsts)
    # broadcasts expect no answer; only the unit with the firmware bug replies
    bugged = {u.unit for u in get_scenario("errors").units if u.answers_broadcast}
    for i, f in enumerate(frames):
        if f.kind == KIND_BROADCAST:
            assert f.unit == 0 and not f.expects_answer
            nxt = frames[i + 1]
            assert nxt.txn == f.txn and nxt.fault == FAULT_BROADCAST_ANSWER and nxt.unit in bugged


def test_default_scenario_is_clean_and_answered():
    frames = sim("default")
    assert {f.kind for f in frames} == {KIND_REQUEST, KIND_RESPONSE}
    reqs = [f for f in frames if f.kind == KIND_REQUEST]
    assert all(f.answered and f.expects_answer for f in reqs)
    assert {f.unit for f in reqs} == {u.unit for u in get_scenario("default").units}
    fcs = {f.function for f in reqs}
    assert {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F, 0x10, 0x08} <= fcs


def test_drive_values_evolve_plausibly():
    """Output frequency follows the written setpoint; setpoints change over time."""
    frames = sim("default", duration=30.0)
    sp_writes = {struct.unpack(">H", f.raw[4:6])[0] for f in frames
                 if f.kind == KIND_REQUEST and f.function == 0x06 and f.raw[2:4] == b"\x20\x01"}
    assert len(sp_writes) >= 2
    out_hz = []
    for req, rsp in zip(frames, frames[1:]):
        if (req.kind == KIND_REQUEST and req.unit == 1 and req.raw[1:6] == bytes.fromhex("03 21 00 00 08")
                and rsp.kind == KIND_RESPONSE):
            words = struct.unpack(">8H", rsp.raw[3:19])
            out_hz.append((words[1], words[2], words[4]))  # command, output (0.01 Hz), DC bus (0.1 V)
    assert len(out_hz) > 50
    assert len({o for _, o, _ in out_hz}) > 10  # it ramps, not a constant
    assert any(c == o and c > 0 for c, o, _ in out_hz)  # and reaches its setpoint
    for (_c0, o0, _), (_c1, o1, _) in zip(out_hz, out_hz[1:]):
        assert abs(o1 - o0) <= 600  # no jumps: at most a few Hz between two polls
    assert all(5000 < dc < 7000 for _, _, dc in out_hz)


# ------------------------------------------------------------------ chunks


def _frame_spans(frames):
    spans, pos = [], 0
    for f in frames:
        spans.append((pos, pos + len(f.raw)))
        pos += len(f.raw)
    return spans


@pytest.mark.parametrize("name", ["default", "fast", "errors"])
def test_usb_chunks_conserve_bytes_glue_and_split(name):
    frames = sim(name)
    chunks = list(usb_chunks(frames, latency_timer_ms=16, packet_size=64, seed=3))
    assert b"".join(c.data for c in chunks) == b"".join(f.raw for f in frames)
    assert all(c.byte_t_ns is None and c.data for c in chunks)
    assert all(a.t_ns <= b.t_ns for a, b in zip(chunks, chunks[1:]))
    ends = [e for _, e in _frame_spans(frames)]
    cuts = list(accumulate(len(c.data) for c in chunks))
    # a read boundary strictly inside a frame splits it; a frame end strictly inside a read glues
    split = len(set(cuts) - set(ends))
    reads = zip([0] + cuts, cuts)
    glued = sum(bisect_right(ends, b - 1) - bisect_right(ends, a) > 0 for a, b in reads)
    assert split > 0 and glued > 0


def test_usb_reads_come_after_their_bytes_and_respect_packet_size():
    frames = sim("stress", duration=3.0)
    arrivals = [t + (f.t_end_ns - f.byte_t_ns[-1]) for f in frames for t in f.byte_t_ns]
    pos = 0
    sizes = []
    for c in usb_chunks(frames, seed=5, hiccup_prob=0.0):
        pos += len(c.data)
        assert c.t_ns >= arrivals[pos - 1]  # causality: a read cannot return a byte early
        sizes.append(len(c.data))
    assert 62 in sizes  # full packets (64 - 2 status bytes) occur at 115200 with a 16 ms timer
    same = list(usb_chunks(frames, seed=5, hiccup_prob=0.0))
    assert same == list(usb_chunks(frames, seed=5, hiccup_prob=0.0))


def test_wire_chunks_carry_per_byte_times_and_flags():
    frames = sim("errors", duration=10.0)
    chunks = list(wire_chunks(frames))
    assert [c.data for c in chunks] == [f.raw for f in frames]
    assert all(c.byte_t_ns == f.byte_t_ns and c.t_ns == f.t_ns for c, f in zip(chunks, frames))
    assert any(c.flags for c in chunks)  # noise bytes with framing errors


# ----------------------------------------------------------------- framer


def _framed(chunks, line):
    fr = RtuFramer(line)
    out = []
    for c in chunks:
        out += fr.feed(c)
    out += fr.flush()
    return out


@pytest.mark.parametrize("name", ["default", "errors", "fast", "stress"])
@pytest.mark.parametrize("seed", [1, 2])
def test_framer_recovers_simulated_frames_from_wire(name, seed):
    frames = sim(name, duration=10.0, seed=seed)
    out = _framed(wire_chunks(frames), LINES[name])
    assert [f.raw for f in out] == [f.raw for f in frames]
    for f, o in zip(frames, out):
        if f.kind in (KIND_REQUEST, KIND_RESPONSE, KIND_EXCEPTION, KIND_BROADCAST):
            assert o.crc_ok and o.t_ns == f.t_ns


@pytest.mark.parametrize("name", ["default", "errors", "fast", "stress"])
def test_framer_keeps_every_valid_frame_from_usb_reads(name):
    """Without host hiccups every CRC-valid frame survives USB gluing and splitting.

    (Regression: a noise byte and a request in one read once became a single
    bad-CRC frame.)
    """
    frames = sim(name, duration=10.0, seed=1)
    out = _framed(usb_chunks(frames, seed=1, hiccup_prob=0.0), LINES[name])
    assert b"".join(o.raw for o in out) == b"".join(f.raw for f in frames)
    got = Counter(o.raw for o in out if o.crc_ok)
    want = Counter(f.raw for f in frames if f.crc_valid)
    assert got == want


def test_framer_keeps_damaged_frame_split_across_usb_reads():
    line = L9600
    # 01 03 21 00 00 08 4e 30 with byte 4 hit (00 -> a4); the latency timer fires after byte 3
    chunks = [Chunk(100_000_000, bytes.fromhex("01 03 21 00")), Chunk(116_000_000, bytes.fromhex("a4 08 4e 30"))]
    out = _framed(chunks, line)
    assert [o.raw.hex(" ") for o in out] == ["01 03 21 00 a4 08 4e 30"]
    assert out[0].crc_ok is False


# -------------------------------------------------------------------- pty

_AWKWARD = bytes([0x0A, 0x0D, 0x03, 0x04, 0x11, 0x13, 0x1A, 0x1C, 0x7F, 0xFF, 0x00, 0x0D, 0x0A])


def _awkward_frames() -> list[WireFrame]:
    """Bytes a cooked tty would translate or act on: LF/CR, ^C, ^D, XON/XOFF, DEL, 0xFF."""
    out, t = [], 0
    for i in range(20):
        adu = bytes([1, 0x03, len(_AWKWARD)]) + _AWKWARD[i % 3 :] + bytes([i])
        raw = adu + crc_bytes(adu)
        times = tuple(t + k * 1_000 for k in range(len(raw)))
        out.append(WireFrame(t, times[-1] + 1_000, raw, times, KIND_RESPONSE, 1, 3))
        t += 2_000_000
    return out


def _read_slave(port: str, n: int, done: threading.Event) -> bytearray:
    fd = os.open(port, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    got = bytearray()
    try:
        while len(got) < n and not done.is_set():
            r, _, _ = select.select([fd], [], [], 0.05)
            if r:
                try:
                    got += os.read(fd, 4096)
                except BlockingIOError:
                    pass
    finally:
        os.close(fd)
    return got


def test_ptybus_carries_bytes_untouched_and_hears_nothing_back():
    frames = _awkward_frames() + sim("errors", duration=1.0)
    want = b"".join(f.raw for f in frames)
    with PtyBus() as bus:
        assert bus.port.startswith("/dev/")
        got = bytearray()
        done = threading.Event()
        reader = threading.Thread(target=lambda: got.extend(_read_slave(bus.port, len(want), done)))
        reader.start()
        try:
            stats = bus.play(frames, speed=20.0)
        finally:
            reader.join(timeout=10)
            done.set()
            reader.join()
        assert stats.frames == len(frames) and stats.bytes == len(want) and not stats.stopped
        assert bytes(got) == want
        assert bus.bytes_received_from_sniffer == 0


def test_ptybus_counts_what_a_non_passive_sniffer_writes_and_survives_reopen():
    import serial

    with PtyBus() as bus:
        with serial.Serial(bus.port, 9600, timeout=0.5) as port:
            port.write(b"\x01\x03\x00\x00\x00\x01\x84\x0a")
            port.flush()
        with serial.Serial(bus.port, 9600, timeout=2.0) as port:  # reopened: the pty is still there
            frames = _awkward_frames()[:3]
            stats = bus.play(frames, speed=1000.0)
            want = b"".join(f.raw for f in frames)
            assert port.read(len(want)) == want
        bus.drain()
        assert stats.bytes == len(want)
        assert bus.bytes_received_from_sniffer == 8
        assert bytes(bus.received) == b"\x01\x03\x00\x00\x00\x01\x84\x0a"


def test_ptybus_play_stops_on_event():
    frames = sim("default", duration=30.0)
    stop = threading.Event()
    stop.set()
    with PtyBus() as bus:
        stats = bus.play(frames, speed=1.0, stop_event=stop)
    assert stats.stopped and stats.frames == 0


def _usb_packets_byte_by_byte(frames, latency_ns, cap, rng):
    """The FTDI rule one byte at a time: the reference for chunks._usb_packets' frame-at-a-time loop."""
    anchor, deadline, buf = None, 0, bytearray()
    for f in frames:
        char = f.t_end_ns - f.byte_t_ns[-1]
        for t, b in zip(f.byte_t_ns, f.raw):
            a = t + char
            if anchor is None:
                anchor = a - rng.randrange(latency_ns)
            if buf and a > deadline:
                yield deadline, bytes(buf)
                buf.clear()
                anchor = deadline
            if not buf:
                deadline = anchor + ((a - anchor) // latency_ns + 1) * latency_ns
            buf.append(b)
            if len(buf) >= cap:
                yield a, bytes(buf)
                buf.clear()
                anchor = a
    if buf:
        yield deadline, bytes(buf)


def test_usb_packets_frame_at_a_time_equal_byte_by_byte():
    import random

    from sniffer.simulator.bus import WireFrame
    from sniffer.simulator.chunks import _usb_packets

    rng = random.Random(11)
    for _ in range(300):
        frames, t = [], rng.randrange(10**9)
        for _ in range(rng.randint(1, 40)):
            n = rng.choice((1, 2, 8, 9, 40, 70, 130, rng.randint(1, 260)))
            char = rng.choice((86_805, 520_833, 1_145_833))  # 115200, 19200, 9600 baud
            times = []
            for _ in range(n):
                times.append(t)
                t += char + (rng.choice((0, 0, 0, rng.randrange(3 * char))) if rng.random() < 0.2 else 0)
            frames.append(WireFrame(times[0], times[-1] + char, bytes(rng.randrange(256) for _ in range(n)),
                                    tuple(times), KIND_RESPONSE, 1, 3))
            t += rng.choice((0, char, 5 * char, 40_000_000))
        latency, cap = rng.choice((1_000_000, 16_000_000)), rng.choice((1, 2, 62, 510))
        seed = rng.randrange(1000)
        want = list(_usb_packets_byte_by_byte(frames, latency, cap, random.Random(seed)))
        assert list(_usb_packets(frames, latency, cap, random.Random(seed))) == want
