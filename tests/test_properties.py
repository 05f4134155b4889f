"""Property tests of framer + pairer + generic decoder (hypothesis).

- arbitrary bytes and gaps: no exception, every byte in exactly one frame;
- any chunking (whole, byte by byte, random) gives identical frames;
- annotation spans lie inside their frame and every code is declared.
"""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from refdata import SIGROK, SIGROK_NAMES, sigrok_line

from decoders.registry import default_registry
from sniffer.framing.crc import crc_bytes
from sniffer.events import CaptureInfo, Chunk
from sniffer.line import LineSettings
from sniffer.capture.pipeline import Pipeline
from sniffer.formats.records import frame_record
from sniffer.formats.bytecsv.reader import open_byte_csv

LINE = LineSettings(19200, "E", 1)
CODEBOOK = default_registry().codebook


def _signature(frames):
    return [
        (f.raw, f.t_ns, f.protocol, f.role, f.pair, f.crc_ok, tuple(a.code for a in f.annotations), f.summary)
        for f in frames
    ]


def _run(chunks, line=LINE):
    p = Pipeline(CaptureInfo(), line, default_registry())
    out = []
    for c in chunks:
        out += p.feed(c)
    return out + p.finish()


def _per_byte(data: bytes, times: list[int]) -> list[Chunk]:
    return [Chunk(times[0], data, tuple(times))] if data else []


def _rechunk(chunks: list[Chunk], cuts: list[int]) -> list[Chunk]:
    """Same bytes and per-byte times, cut at other places (channels kept)."""
    out = []
    for c in chunks:
        i = 0
        n = len(c.data)
        k = 0
        while i < n:
            step = max(1, cuts[k % len(cuts)]) if cuts else n
            k += 1
            j = min(n, i + step)
            flags = tuple((o - i, fl) for o, fl in c.flags if i <= o < j)
            out.append(Chunk(c.byte_t_ns[i], c.data[i:j], c.byte_t_ns[i:j], flags, c.channel))
            i = j
    return out


# a line of bytes: runs of bytes separated by gaps, some runs real frames
_frame = st.builds(
    lambda unit, fc, body: bytes([unit, fc]) + body + crc_bytes(bytes([unit, fc]) + body),
    st.integers(0, 255), st.sampled_from([1, 2, 3, 4, 5, 6, 15, 16, 0x83, 0x2B, 0x41]),
    st.binary(min_size=0, max_size=12),
)
_run_bytes = st.one_of(st.binary(min_size=1, max_size=40), _frame)
_gap_chars = st.one_of(st.just(0.0), st.floats(0.0, 1.4), st.floats(1.5, 3.4), st.floats(3.5, 200.0))


@st.composite
def line_traffic(draw):
    runs = draw(st.lists(st.tuples(_gap_chars, _run_bytes), min_size=1, max_size=25))
    char = LINE.char_ns
    t = 0
    data = bytearray()
    times = []
    for gap, run in runs:
        t += int(gap * char)
        for b in run:
            times.append(t)
            data.append(b)
            t += char
    return bytes(data), times


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(line_traffic(), st.lists(st.integers(1, 30), min_size=1, max_size=10))
def test_arbitrary_bytes_conserved_and_chunking_invariant(traffic, cuts):
    data, times = traffic
    whole = _run(_per_byte(data, times))
    assert b"".join(f.raw for f in whole) == data
    assert [f.index for f in whole] == list(range(len(whole)))
    for f in whole:
        assert f.raw
        for a in f.annotations:
            assert 0 <= a.start < a.end <= len(f.raw), (a, f)
            assert a.code in CODEBOOK, a.code
        frame_record(f, 0)  # serialisable
    sig = _signature(whole)
    assert _signature(_run(_rechunk(_per_byte(data, times), [1]))) == sig
    assert _signature(_run(_rechunk(_per_byte(data, times), cuts))) == sig


@settings(max_examples=100, deadline=None)
@given(st.binary(min_size=1, max_size=600), st.lists(st.integers(1, 64), min_size=1, max_size=8))
def test_per_read_chunks_of_garbage(data, cuts):
    """USB-style reads (no per-byte times): no exception, byte conservation."""
    chunks = []
    t = 1_000_000
    i = 0
    k = 0
    while i < len(data):
        j = min(len(data), i + cuts[k % len(cuts)])
        k += 1
        t += (j - i) * LINE.char_ns + (k % 3) * 5_000_000
        chunks.append(Chunk(t, data[i:j]))
        i = j
    frames = _run(chunks)
    assert b"".join(f.raw for f in frames) == data


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SIGROK_NAMES), st.lists(st.integers(1, 50), min_size=1, max_size=12))
def test_real_capture_any_chunking_same_frames(name, cuts):
    info, events = open_byte_csv(str(SIGROK / f"{name}.bytes.csv"))
    chunks = list(events)
    line = sigrok_line(name)
    whole = _signature(_run(chunks, line))
    assert _signature(_run(_rechunk(chunks, cuts), line)) == whole


def test_real_capture_byte_by_byte_same_frames():
    for name in SIGROK_NAMES:
        info, events = open_byte_csv(str(SIGROK / f"{name}.bytes.csv"))
        chunks = list(events)
        line = sigrok_line(name)
        assert _signature(_run(_rechunk(chunks, [1]), line)) == _signature(_run(chunks, line)), name


def test_valid_frame_followed_by_zeros_is_not_swallowed():
    """CRC residual stays 0 when 0x00 bytes follow a frame: structure must cut it."""
    frame = bytes.fromhex("010303e80002447b")
    data = frame + b"\x00\x00\x00"
    times = [i * LINE.char_ns for i in range(len(data))]
    frames = _run(_per_byte(data, times))
    assert frames[0].raw == frame and frames[0].crc_ok
    assert frames[1].is_noise and frames[1].raw == b"\x00\x00\x00"


def test_glued_frames_in_one_read_are_cut():
    """A USB read holding request + response + next request (turnaround < t3.5)."""
    req = bytes.fromhex("010303e80002447b")
    rsp = bytes.fromhex("010304526657077566")
    chunks = [Chunk(50_000_000, req + rsp + req)]
    frames = _run(chunks)
    assert [f.raw for f in frames] == [req, rsp, req]
    assert [f.role for f in frames] == ["request", "response", "request"]
    assert frames[1].pair == 0 and all(f.time_source == "read" for f in frames)


def test_frame_split_across_reads_is_rejoined():
    rsp = bytes.fromhex("010304526657077566")
    chunks = [Chunk(10_000_000, rsp[:3]), Chunk(26_000_000, rsp[3:])]
    frames = _run(chunks)
    assert [f.raw for f in frames] == [rsp]


def test_noise_then_frame_in_one_read():
    noise = bytes.fromhex("ff13a5")
    req = bytes.fromhex("010303e80002447b")
    frames = _run([Chunk(10_000_000, noise + req)])
    assert [f.raw for f in frames] == [noise, req]
    assert frames[0].protocol == "noise" and frames[0].role == "noise" and frames[0].crc_ok is None


class _SlowRtuFramer:
    """RtuFramer without its tight per-read loop: the reference the fast path must equal."""

    def __new__(cls, line):
        from sniffer.framing.rtu import RtuFramer

        f = RtuFramer(line)
        f._fast = lambda out: None
        return f


def _frames_of(framer, chunks):
    out = []
    for c in chunks:
        out += framer.feed(c)
    out += framer.flush()
    return [(f.raw, f.t_ns, f.t_end_ns, f.protocol, f.role_fits, f.crc_ok, f.idle_before_ns,
             tuple(a.code for a in f.annotations)) for f in out]


def test_fast_path_equals_rule_by_rule_path_on_usb_captures():
    from sniffer.framing.rtu import RtuFramer
    from sniffer.simulator.bus import simulate
    from sniffer.simulator.chunks import usb_chunks
    from sniffer.simulator.scenario import get_scenario

    for name, line in (("errors", LineSettings(19200, "E", 1)), ("fast", LineSettings(115200))):
        chunks = list(usb_chunks(simulate(get_scenario(name), line, 3.0, 5), seed=5))
        fast = _frames_of(RtuFramer(line), chunks)
        assert fast == _frames_of(_SlowRtuFramer(line), chunks), name
        assert len(fast) > 100


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(_frame, st.binary(min_size=1, max_size=12)), min_size=1, max_size=30),
       st.lists(st.integers(1, 40), min_size=1, max_size=6))
def test_fast_path_equals_rule_by_rule_path_on_random_reads(runs, cuts):
    from sniffer.framing.rtu import RtuFramer

    data = b"".join(runs)
    chunks, t, i, k = [], 0, 0, 0
    while i < len(data):
        j = min(len(data), i + cuts[k % len(cuts)])
        t += (j - i) * LINE.char_ns + (k % 4) * 3_000_000
        chunks.append(Chunk(t, data[i:j]))
        i, k = j, k + 1
    assert _frames_of(RtuFramer(LINE), chunks) == _frames_of(_SlowRtuFramer(LINE), chunks)
