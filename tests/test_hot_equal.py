"""The compiled hot path (sniffer._hot) against the pure-Python one, the reference: byte for byte.

Two halves.  Whole runs: every capture of captures/manifest.toml (and a stress simulation) through every
output (replay text, jsonl and pcapng on stdout; export to mcap, csv, jsonl, pcap, pcapng), in one child
process with SNIFFER_PURE=1 and one without; every file must be equal.  Functions: each compiled function
and the Python one it copies, on seeded random and adversarial inputs (hypothesis): the RTU framer on glued,
split, truncated and CRC-colliding frames in reads of every size and gap, at every baud; /raw messages as
this sniffer writes them and damaged; MCAP chunks with cut, short and foreign records.

Without the extension built, the compiled half is skipped with the reason; on CI (CI=true) that is a failure.
"""

from __future__ import annotations

import os
import random
import struct
import subprocess
import sys
import tomllib
import zlib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sniffer.events import Chunk, Gap, Tick
from sniffer.formats.mcap import format as mcap_format
from sniffer.formats.mcap import scan as mcap_scan
from sniffer.frame import Frame
from sniffer.framing.crc import crc_bytes, crc16_raw
from sniffer.framing.rtu import RtuFramer
from sniffer.line import LineSettings

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"

try:
    from sniffer import _hot as HOT
    WHY = ""
except ImportError as e:
    HOT = None
    WHY = f"sniffer._hot is not built ({e})"


def _need_hot() -> None:
    if HOT is None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"{WHY}: on CI the compiled path must be built")
        pytest.skip(WHY)


# ------------------------------------------------------------------ whole runs, in two child processes

DRIVER = r"""
import contextlib, io, json, os, sys
from sniffer.cli import main
out = sys.argv[1]
with open(sys.argv[2]) as f:
    jobs = json.load(f)


class Kept(io.BytesIO):
    def close(self):  # a writer closing stdout when done: keep what it wrote
        pass


for name, argv, stdout in jobs:
    buf = Kept()
    text = io.TextIOWrapper(buf, encoding="utf-8", write_through=True)
    err = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(err):
        rc = main([a.replace("{out}", out) for a in argv])
    text.flush()
    if stdout:
        with open(os.path.join(out, name), "wb") as f:
            f.write(buf.getvalue())
    with open(os.path.join(out, name + ".rc"), "w") as f:
        f.write(f"{rc}\n" + err.getvalue().replace(out, "{out}"))
"""

REPLAY_FORMATS = ("text", "jsonl", "pcapng")
EXPORTS = ("mcap", "csv", "jsonl", "pcap", "pcapng")


def _jobs(stress: Path) -> list:
    manifest = tomllib.loads((CAPTURES / "manifest.toml").read_text())
    caps = [(c["name"], str(CAPTURES / c["file"]), [f for f in c["flags"] if f != "--findings"])
            for c in manifest["capture"]]
    caps.append(("stress", str(stress), []))
    jobs = []
    for name, path, flags in caps:
        for fmt in REPLAY_FORMATS:
            jobs.append((f"{name}.replay.{fmt}", ["replay", path, "--jobs", "1", "--format", fmt, *flags], True))
        for to in EXPORTS:
            jobs.append((f"{name}.export.{to}", ["export", path, "--to", to, "--out", f"{{out}}/{name}.x.{to}",
                                                 "--jobs", "1", *flags], False))
    return jobs


def _run_all(out: Path, jobs: list, pure: bool) -> None:
    import json

    env = dict(os.environ)
    env.pop("SNIFFER_PURE", None)
    if pure:
        env["SNIFFER_PURE"] = "1"
    out.mkdir()
    spec = out.parent / "jobs.json"
    spec.write_text(json.dumps(jobs))
    run = subprocess.run([sys.executable, "-c", DRIVER, str(out), str(spec)], env=env, capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]


def test_every_capture_and_format_alike_on_both_paths(tmp_path):
    """Both paths give the same bytes for every capture in captures/ and every output format."""
    _need_hot()
    stress = tmp_path / "stress.mcap"
    subprocess.run([sys.executable, "-m", "sniffer", "simulate", "--out", str(stress), "--scenario", "stress",
                    "--duration", "20", "--seed", "3"], check=True, capture_output=True, timeout=300)
    jobs = _jobs(stress)
    _run_all(tmp_path / "pure", jobs, pure=True)
    _run_all(tmp_path / "hot", jobs, pure=False)
    pure = sorted(p.name for p in (tmp_path / "pure").iterdir())
    assert pure == sorted(p.name for p in (tmp_path / "hot").iterdir())
    assert len(pure) >= len(jobs) * 2 - len(EXPORTS)  # every run left its exit code (and its output)
    differ = [n for n in pure if (tmp_path / "pure" / n).read_bytes() != (tmp_path / "hot" / n).read_bytes()]
    assert not differ, f"the compiled path differs from the pure one in {differ[:10]}"
    # the runs did something: the stress capture's text is one line a frame
    assert (tmp_path / "pure" / "stress.replay.text").read_bytes().count(b"\n") > 1000
    assert (tmp_path / "pure" / "stress.export.mcap.rc").read_text().startswith("0")


def test_version_says_which_path_runs():
    env = dict(os.environ)
    env.pop("SNIFFER_PURE", None)
    pure = subprocess.run([sys.executable, "-m", "sniffer", "--version"], env={**env, "SNIFFER_PURE": "1"},
                          capture_output=True, text=True, timeout=60)
    assert pure.stdout.splitlines()[1] == "hot path: pure Python (SNIFFER_PURE is set)"
    hot = subprocess.run([sys.executable, "-m", "sniffer", "--version"], env=env, capture_output=True, text=True,
                         timeout=60)
    want = "hot path: compiled (sniffer._hot)" if HOT is not None else "hot path: pure Python (sniffer._hot"
    assert hot.stdout.splitlines()[1].startswith(want)


# ------------------------------------------------------------------ functions: the RTU framer


class PureRtuFramer(RtuFramer):
    """The reference: RtuFramer with `_fast` in Python."""

    _compiled_fast = None


class HotRtuFramer(RtuFramer):
    _compiled_fast = None if HOT is None else staticmethod(HOT.rtu_fast)


def _frame_state(f: Frame) -> tuple:
    return tuple(repr(getattr(f, s)) for s in Frame.__slots__ if s not in ("peer", "encoded", "_points"))


def _frames(framer_class, line: LineSettings, events: list) -> list:
    """Every frame and, after each event, the framer's state (what the compiled loop writes back)."""
    fr = framer_class(line)
    out = []
    for ev in events:
        if type(ev) is Chunk:
            got = fr.feed(ev)
        else:
            got = fr.tick(ev)
        out += [_frame_state(f) for f in got]
        out.append(("state", fr.index, fr.pos, fr.prev_frame_end_ns, fr._need, repr(fr._last_good)))
    out += [_frame_state(f) for f in fr.flush()]
    return out


def _good(rng: random.Random) -> bytes:
    unit = rng.choice((1, 2, 3, 17, 247, 0, 248))
    fc = rng.choice((1, 2, 3, 4, 5, 6, 8, 15, 16, 0x83, 0x90, 0x14, 0x2B, 0x41, 0x80))
    kind = rng.random()
    if fc in (1, 2, 3, 4):
        if kind < 0.5:
            body = bytes((unit, fc)) + rng.randbytes(2) + bytes((0, rng.randint(0, 125)))
        else:
            n = rng.choice((0, 1, 2, 3, 4, 6, 8, 20, 250, 255))
            body = bytes((unit, fc, n)) + rng.randbytes(n)
    elif fc in (15, 16):
        if kind < 0.5:
            body = bytes((unit, fc)) + rng.randbytes(4)
        else:
            n = rng.choice((0, 1, 2, 4, 6, 100, 246))
            body = bytes((unit, fc)) + rng.randbytes(4) + bytes((n,)) + rng.randbytes(n)
    elif fc & 0x80:
        body = bytes((unit, fc, rng.randint(0, 12)))
    else:
        body = bytes((unit, fc)) + rng.randbytes(rng.choice((0, 2, 4, 7)))
    return body + crc_bytes(body)


def _line_bytes(rng: random.Random) -> bytes:
    """Frames glued, cut, damaged, with noise and zeros between; some CRC collisions (a frame + 0x00)."""
    out = bytearray()
    for _ in range(rng.randint(0, 40)):
        r = rng.random()
        f = _good(rng)
        if r < 0.6:
            out += f
        elif r < 0.7:
            out += f[: rng.randint(0, len(f))]  # truncated
        elif r < 0.8:
            b = bytearray(f)
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)  # damaged
            out += b
        elif r < 0.88:
            out += f + b"\x00" * rng.randint(1, 3)  # the 0x00 a line driver leaves: CRC-16 holds one longer
        else:
            out += rng.randbytes(rng.randint(0, 12))  # noise
    return bytes(out)


BAUDS = (1200, 9600, 19200, 115200, 921600)


def _events(rng: random.Random, data: bytes, baud: int) -> list:
    """Reads of every size, per read (mostly) or per byte, with gaps from none to past t3.5 and ticks."""
    line = LineSettings(baud, rng.choice("NEO"), 1, 8)
    char = line.char_ns
    t = rng.choice((0, 1_000_000, 2**62))  # 2**62: times near the end of 64 bits
    events = []
    i = 0
    while i < len(data):
        n = rng.choice((1, 2, 3, 7, 8, 16, 32, 64, 300))
        piece = data[i:i + n]
        i += n
        t += rng.choice((0, char, 2 * char, line.t35_ns, 60_000_000, 10**9)) + len(piece) * char
        channel = rng.choice(("", "", "", "master"))
        if rng.random() < 0.1:
            bt = tuple(t - (len(piece) - k) * char for k in range(len(piece)))
            events.append(Chunk(bt[0], piece, bt, (), channel))
        else:
            events.append(Chunk(t, piece, None, (), channel, "", rng.choice((None, None, 5_000_000))))
        if rng.random() < 0.1:
            t += rng.choice((char, 100_000_000))
            events.append(t)  # a tick
    return line, events


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**32), st.sampled_from(BAUDS))
def test_rtu_framer_alike_on_random_lines(seed, baud):
    _need_hot()
    rng = random.Random(seed)
    line, events = _events(rng, _line_bytes(rng), baud)
    assert _frames(HotRtuFramer, line, events) == _frames(PureRtuFramer, line, events)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600), st.integers(1, 64), st.sampled_from(BAUDS), st.booleans())
def test_rtu_framer_alike_on_any_bytes(data, size, baud, gaps):
    """Arbitrary bytes (0-length included) in reads of one size, back to back or past t3.5."""
    _need_hot()
    line = LineSettings(baud, "N", 1, 8)
    t, events = 0, []
    for i in range(0, len(data), size):
        t += (line.t35_ns + 80_000_000 if gaps else 0) + size * line.char_ns
        events.append(Chunk(t, data[i:i + size]))
    assert _frames(HotRtuFramer, line, events) == _frames(PureRtuFramer, line, events)


def test_rtu_framer_alike_on_a_huge_read():
    """One read of 100,000 bytes: thousands of frames in one call."""
    _need_hot()
    rng = random.Random(7)
    data = b"".join(_good(rng) for _ in range(8000))[:100_000]
    line = LineSettings(115200, "N", 1, 8)
    events = [Chunk(10**12, data)]
    hot, pure = _frames(HotRtuFramer, line, events), _frames(PureRtuFramer, line, events)
    assert hot == pure and len(pure) > 1000


def test_rtu_times_past_64_bits_alike():
    """Times past 64 bits: the compiled loop hands them to the Python rules, which give the same frames."""
    _need_hot()
    line = LineSettings(9600, "N", 1, 8)
    f = _good(random.Random(1))
    events = [Chunk(2**70, f * 3), Chunk(2**70 + 10**9, f)]
    assert _frames(HotRtuFramer, line, events) == _frames(PureRtuFramer, line, events)


def test_crc16_alike():
    _need_hot()
    rng = random.Random(5)
    for n in (0, 1, 2, 3, 8, 255, 256, 4096):
        for _ in range(20):
            b = rng.randbytes(n)
            assert HOT.crc16(b) == crc16_raw(b)


# ------------------------------------------------------------------ functions: /raw messages

_text = st.text(max_size=6)
_chunks = st.builds(
    lambda t, data, per_byte, flags, channel, link, unseen, de, packet: Chunk(
        t, data, tuple(t + 3 * k for k in range(len(data))) if per_byte else None,
        tuple((k % max(1, len(data)), f) for k, f in enumerate(flags)), channel, link, unseen, de, packet),
    st.integers(-2**63, 2**64), st.binary(max_size=40), st.booleans(), st.lists(st.sampled_from(("framing", "parity")),
                                                                               max_size=2),
    st.one_of(st.just(""), _text), st.one_of(st.just(""), _text), st.one_of(st.none(), st.integers(0, 10**9)),
    st.one_of(st.none(), st.tuples(st.one_of(st.none(), st.integers()), st.one_of(st.none(), st.integers()))),
    st.booleans())
_events_st = st.one_of(_chunks, st.builds(Tick, st.integers(-2**63, 2**64), st.one_of(st.just(""), _text)),
                       st.builds(Gap, st.integers(0, 2**40), st.integers(0, 2**40), _text, _text))


def _decoded(decode, data: bytes):
    try:
        return ("ok", decode(data))
    except Exception as e:  # noqa: BLE001 - the same exception type on both paths is what is compared
        return ("error", type(e).__name__)


@settings(max_examples=400, deadline=None)
@given(_events_st)
def test_raw_event_alike(ev):
    _need_hot()
    data = mcap_format.encode_event(ev)
    assert _decoded(mcap_format.decode_event, data) == _decoded(mcap_format.decode_event_py, data) == ("ok", ev)


@settings(max_examples=400, deadline=None)
@given(_events_st, st.integers(0, 10**6), st.integers(0, 255), st.booleans())
def test_damaged_raw_event_alike(ev, where, value, cut):
    """A /raw message cut off or with one byte changed: the same event, or the same error."""
    _need_hot()
    data = bytearray(mcap_format.encode_event(ev))
    k = where % (len(data) + 1)
    if cut:
        del data[k:]
    elif k < len(data):
        data[k] = value
    data = bytes(data)
    assert _decoded(mcap_format.decode_event, data) == _decoded(mcap_format.decode_event_py, data)


@pytest.mark.parametrize("data", [
    b'{"kind":"chunk","t_ns":1,"data":"0A0b","byte_dt_ns":null,"flags":[],"channel":""}',  # upper case hex
    b'{"kind":"chunk","t_ns":01,"data":"","byte_dt_ns":null,"flags":[],"channel":""}',  # not JSON
    b'{"kind":"chunk","t_ns":1.5,"data":"","byte_dt_ns":null,"flags":[],"channel":""}',
    b'{"kind":"chunk","t_ns":1,"data":"00","byte_dt_ns":[1,2],"flags":[],"channel":""}',  # lengths differ
    b'{"kind":"chunk","t_ns":1,"data":"0","byte_dt_ns":null,"flags":[],"channel":""}',  # odd hex
    b'{"kind":"chunk","t_ns":1,"data":"00","byte_dt_ns":null,"flags":[],"channel":"\\u0041"}',
    b'{"kind":"chunk","t_ns":1,"data":"00","byte_dt_ns":null,"flags":[],"channel":"","link":""}',
    b'{"kind":"chunk","t_ns":1,"data":"00","byte_dt_ns":null,"flags":[],"channel":""} ',
    b'{"kind":"tick","t_ns":99999999999999999999}', b'{"kind":"tick","t_ns":-5,"link":"b"}', b'{"kind":"x","t_ns":1}',
    b'', b'{', b'null',
])
def test_odd_raw_messages_alike(data):
    _need_hot()
    assert _decoded(mcap_format.decode_event, data) == _decoded(mcap_format.decode_event_py, data)


# ------------------------------------------------------------------ functions: MCAP chunks


def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def _message(cid: int, seq: int, data: bytes) -> bytes:
    return _record(0x05, struct.pack("<HIQQ", cid, seq, seq * 7, seq * 11) + data)


def _channel(cid: int, topic: str) -> bytes:
    def s(x: str) -> bytes:
        b = x.encode()
        return struct.pack("<I", len(b)) + b
    return _record(0x04, struct.pack("<HH", cid, 1) + s(topic) + s("json") + struct.pack("<I", 0))


def _chunk_body(records: bytes) -> bytes:
    return (struct.pack("<QQQI", 0, 0, len(records), zlib.crc32(records)) + struct.pack("<I", 0)
            + struct.pack("<Q", len(records)) + records)


def _walked(body: bytes, messages) -> tuple:
    from mcap.records import Channel

    known = {1: Channel(id=1, schema_id=1, topic="/raw", message_encoding="json", metadata={}),
             2: Channel(id=2, schema_id=1, topic="/frames", message_encoding="json", metadata={})}
    try:
        return ("ok", repr(mcap_scan._walk_chunk(body, known, lambda t: t != "/raw", messages)))
    except Exception as e:  # noqa: BLE001 - the same error on both paths
        return ("error", type(e).__name__, str(e))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(("msg", "chan", "cut", "short", "other")), st.integers(0, 6),
                          st.binary(max_size=30)), max_size=20))
def test_chunk_walk_alike(parts):
    """Messages of kept, skipped and unknown channels, channels defined midway, records cut off, too short
    for a message, of other kinds: the same records, or the same error."""
    _need_hot()
    records = bytearray()
    for kind, cid, data in parts:
        if kind == "msg":
            records += _message(cid, len(records), data)
        elif kind == "chan":
            records += _channel(cid, "/raw" if cid % 2 else "/values/x")
        elif kind == "cut":
            records += _message(cid, 1, data)[: 5 + len(data) // 2]
        elif kind == "short":
            records += _record(0x05, data[:21])
        else:
            records += _record(0x07, data)
    body = _chunk_body(bytes(records))
    assert _walked(body, HOT.chunk_messages) == _walked(body, None)


def test_capture_chunks_walk_alike():
    """Every chunk of the MCAP captures in captures/, walked both ways."""
    _need_hot()
    n = 0
    for path in sorted(CAPTURES.rglob("*.mcap")):
        data = path.read_bytes()
        pos = 8
        while pos + 9 <= len(data):
            op, length = struct.unpack_from("<BQ", data, pos)
            if op == 0x06:
                body = data[pos + 9:pos + 9 + length]
                assert _walked(body, HOT.chunk_messages) == _walked(body, None)
                n += 1
            pos += 9 + length
    assert n > 10


# ------------------------------------------------------------------ functions: table rows and CSV text

_cell = st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.floats(allow_nan=True, allow_infinity=True),
                  st.text(max_size=8), st.sampled_from(['"', 'a"b""', "\ud800", "é", ""]),
                  st.lists(st.integers(0, 9), max_size=2))


def _csv(fn, rows, columns):
    try:
        return ("ok", fn(rows, columns))
    except Exception as e:  # noqa: BLE001 - the same error on both paths
        return ("error", type(e).__name__)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.tuples(_cell, _cell, _cell, _cell), max_size=6), st.permutations(("str", "int", "float", "bool")))
def test_csv_text_alike(rows, kinds):
    """Cells of every type in columns of every kind: the same bytes (or error) as the Python writer."""
    _need_hot()
    from sniffer.formats import csvexport

    columns = tuple((f"c{k}", kind) for k, kind in enumerate(kinds))
    assert _csv(csvexport.csv_text, rows, columns) == _csv(csvexport.csv_text_py, rows, columns)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**63, 2**63 - 1),
                          st.text(max_size=6), st.booleans()), min_size=1, max_size=8))
def test_csv_text_of_plain_cells_alike(rows):
    """Cells of their columns' own types (what the compiled writer writes itself): floats of every size
    (exponents, 1e10 and up, -0.0, inf, nan), ints of 64 bits, strings with quotes and non-ASCII."""
    _need_hot()
    from sniffer.formats import csvexport

    columns = (("f", "float"), ("i", "int"), ("s", "str"), ("b", "bool"))
    assert HOT.csv_text(rows, ("float", "int", "str", "bool"), csvexport.float_text) is not None
    assert csvexport.csv_text(rows, columns) == csvexport.csv_text_py(rows, columns)


_point = st.one_of(
    st.fixed_dictionaries({}, optional={
        "name": st.one_of(st.none(), st.text(max_size=4)), "address": st.one_of(st.none(), st.integers(0, 65535)),
        "raw": st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.floats(), st.text(max_size=3)),
        "value": _cell, "unit": st.one_of(st.none(), st.text(max_size=3)),
        "id": st.one_of(st.none(), st.text(max_size=3)),
        "text": st.one_of(st.none(), st.just(""), st.text(max_size=4))}),
    st.builds(dict))


@settings(max_examples=400, deadline=None)
@given(st.lists(_point, min_size=1, max_size=6), st.one_of(st.none(), st.just("a")))
def test_point_rows_alike(points, link):
    _need_hot()
    from sniffer.formats import rows

    head = (3, 0.5, 1, 3, "response", True, "generic")
    try:
        want = ("ok", rows.point_rows_py(points, head, link))
    except Exception as e:  # noqa: BLE001 - the same error on both paths
        want = ("error", type(e).__name__)
    try:
        got = ("ok", HOT.point_rows(points, head, link, rows._text))
    except Exception as e:  # noqa: BLE001
        got = ("error", type(e).__name__)
    assert repr(got) == repr(want)  # repr: nan is not equal to itself


# ------------------------------------------------------------------ functions: text lines


@st.composite
def _any_frame(draw):
    from sniffer.codes import note
    from sniffer.codes import NOISE as NOISE_CODE

    protocol = draw(st.sampled_from(("modbus-rtu", "modbus-rtu", "noise", "modbus-ascii")))
    f = Frame(draw(st.integers(0, 2**64)), draw(st.integers(-2**64, 2**64)), 0, draw(st.binary(max_size=30)), protocol,
              draw(st.one_of(st.none(), st.integers(-1, 300))), draw(st.one_of(st.none(), st.integers(-1, 300))),
              time_source=draw(st.sampled_from(("byte", "read", "none"))))
    f.role = draw(st.sampled_from(("request", "response", "unknown", "noise")))
    f.pair = draw(st.one_of(st.none(), st.integers(0, 2**70)))
    f.latency_ms = draw(st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True),
                                  st.floats(-1e6, 1e6)))
    f.crc_ok = draw(st.one_of(st.none(), st.booleans()))
    f.model = draw(st.one_of(st.none(), st.sampled_from(("generic", "a510", "")), st.text(max_size=4)))
    f.summary = draw(st.text(max_size=20))
    f.noise_reason = "why"
    if draw(st.booleans()):
        f.de_on_ns = draw(st.one_of(st.none(), st.integers(-10**6, 10**6)))
    if draw(st.integers(0, 3)) == 0:
        f.annotations.append(note(NOISE_CODE, "x", 0, 1))
    return f


@settings(max_examples=500, deadline=None)
@given(_any_frame(), st.integers(-2**64, 2**64), st.sampled_from((0, 0, 3)))
def test_frame_line_alike(f, t0, link_width):
    _need_hot()
    from sniffer.formats import text

    f.link = "ab"

    def line(fn):
        try:
            return "ok", fn(f, t0, link_width)
        except Exception as e:  # noqa: BLE001 - the same error on both paths
            return "error", type(e).__name__

    assert line(text.frame_line) == line(text.frame_line_py)


def test_frame_line_compiled_for_the_common_frame():
    """The compiled writer does write the common frame's line (not only hand it back)."""
    _need_hot()
    from sniffer.formats import text

    f = Frame(7, 1_500_000_000, 1_600_000_000, bytes.fromhex("010300000002C40B"), "modbus-rtu", 1, 3, crc_ok=True)
    f.role, f.pair, f.latency_ms, f.summary = "request", 8, 12.25, "read holding 0..1 (2)"
    want = "    1.499000    ->REQ u1   fc03 #7 #8   12.2ms  read holding 0..1 (2)"
    assert HOT.frame_line(f, 1_000_000) == text.frame_line_py(f, 1_000_000) == want


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from((0x07, 0x07, 0x07, 0x06, 0x05)), st.integers(0, 5), st.integers(-2, 2)),
                max_size=12), st.integers(0, 40))
def test_message_index_run_alike(records, cut):
    """Message index records (one per channel after each chunk): whole ones, with a wrong count or length,
    of another kind, cut off: as far as the Python loop reads, the compiled one reads."""
    _need_hot()
    buf = bytearray()
    for op, entries, skew in records:
        body = struct.pack("<HI", 1, 16 * entries + max(0, skew)) + bytes(16 * entries)
        buf += struct.pack("<BQ", op, max(0, len(body) + skew)) + body
    buf = bytes(buf[: max(0, len(buf) - cut)])
    assert HOT.index_run(buf) == mcap_scan._index_run_py(buf)


# ------------------------------------------------------------------ line health: analysis/linehealth.py

def _called(method):
    try:
        return method()
    except Exception as e:  # noqa: BLE001 - a window of odd values fails in the reference: alike here
        return type(e).__name__


def _health_state(h) -> tuple:
    return (h.link, h.window_ns, h.min_span_ns, h.frames, h.nbytes, h.bad, h.bad_bytes, list(h.kinds), h.broken,
            h.warnings, h.window(), _called(h.enough), _called(h.most_bad), _called(h.mostly_good))


def _health_run(make, steps) -> list:
    """Each step's result (a Change, an exception's type) and the state after it."""
    h, out = make(), []
    for op, *args in steps:
        try:
            out.append(h.add(*args) if op == "add" else h.advance(*args))
        except Exception as e:  # noqa: BLE001 - the reference's error is part of what must match
            out.append(type(e).__name__)
        out.append(_health_state(h))
    return out


def _compiled_health(**kw):
    from sniffer.analysis import linehealth

    h = linehealth.LineHealth("a", **kw)
    return h


_times = st.integers(0, 40).map(lambda k: k * 125_000_000)  # steps of 1/8 s: within, across and past the window
_health_steps = st.lists(st.one_of(
    st.tuples(st.just("add"), _times, st.integers(0, 300), st.sampled_from((None, None, 0, 1, 2))),
    st.tuples(st.just("advance"), _times)), max_size=120)


def _cumulative(steps):
    """Times in order, as a capture gives them (each step's time is a gap after the last)."""
    t, out = 10**12, []
    for op, dt, *rest in steps:
        t += dt
        out.append((op, t, *rest))
    return out


@settings(max_examples=300, deadline=None)
@given(_health_steps, st.sampled_from((1, 2, 8, 20, 200)), st.sampled_from((0.0, 0.5, 1.0, 5.0)))
def test_line_health_alike(steps, max_frames, window_s):
    from sniffer.analysis.linehealth import LineHealthPy

    _need_hot()
    steps = _cumulative(steps)
    kw = {"max_frames": max_frames, "window_s": window_s}
    compiled = _compiled_health(**kw)
    assert not compiled.handed_over and type(compiled).__name__ == "LineHealth"
    assert _health_run(lambda: _compiled_health(**kw), steps) == _health_run(lambda: LineHealthPy("a", **kw), steps)


def test_line_health_breaks_and_recovers_alike():
    """A line that breaks, recovers and breaks again: the same Changes, field by field."""
    from sniffer.analysis.linehealth import LineHealthPy

    _need_hot()
    rng = random.Random(3)
    steps, t = [], 0
    for phase in (None, 0, None, 2, 1, None, 0):
        for _ in range(rng.randint(50, 400)):
            t += rng.randint(1, 60_000_000)
            steps.append(("add", t, rng.randint(4, 260), phase if rng.random() < 0.9 else None))
    got, want = _health_run(_compiled_health, steps), _health_run(lambda: LineHealthPy("a"), steps)
    assert got == want
    assert sum(1 for x in want if x is not None and not isinstance(x, tuple)) >= 4  # it broke and recovered


@pytest.mark.parametrize("odd", [2**61 + 1, -(2**62), 2**70, 1.5, True, "x", None])
def test_line_health_hands_odd_times_to_the_reference(odd):
    """A time the C window does not keep hands the state over; from then on the reference runs."""
    from sniffer.analysis.linehealth import LineHealthPy

    _need_hot()
    steps = [("add", 10**9 + k * 10**8, 40, k % 2 or None) for k in range(30)] + [("add", odd, 40, 2)]
    steps += [("add", 2**62 + k, 9, 0) for k in range(12)] + [("advance", 2**63)]
    assert _health_run(_compiled_health, steps) == _health_run(lambda: LineHealthPy("a"), steps)


@pytest.mark.parametrize("nbytes,bad", [(2**41, None), (-1, 0), (3, 3), (3, -1), (3, 1.0), (3, "x"), (2**80, 1)])
def test_line_health_hands_odd_frames_to_the_reference(nbytes, bad):
    from sniffer.analysis.linehealth import LineHealthPy

    _need_hot()
    steps = [("add", 10**9 + k * 10**8, 40, 2) for k in range(20)] + [("add", 4 * 10**9, nbytes, bad)]
    steps += [("add", 4 * 10**9 + k, 9, None) for k in range(12)]
    assert _health_run(_compiled_health, steps) == _health_run(lambda: LineHealthPy("a"), steps)


@pytest.mark.parametrize("kw", [{"max_frames": 5000}, {"max_frames": None}, {"max_frames": 0},
                                {"window_s": 1e10}, {"window_s": -1.0}, {"window_s": float("nan")}])
def test_line_health_odd_windows_are_the_reference(kw):
    from sniffer.analysis.linehealth import LineHealth, LineHealthPy

    _need_hot()
    try:
        want = type(LineHealthPy("a", **kw))
    except Exception as e:  # noqa: BLE001 - the same error either way
        with pytest.raises(type(e)):
            LineHealth("a", **kw)
        return
    assert type(LineHealth("a", **kw)) is want


def _warnings(compiled: bool, frames) -> tuple:
    """What a LineWarning says of `frames` on one path, and every link's state after."""
    from sniffer.analysis.linehealth import LineHealthPy, LineWarning, LineWatch

    class PyWatch(LineWatch):
        health = LineHealthPy

    class PyWarning(LineWarning):
        _compiled_frame = None

    said: list[str] = []
    w = (LineWarning if compiled else PyWarning)(lambda info, link: f"hint {link}", said.append)
    if not compiled:
        w.watch = PyWatch()
    for f in frames:
        w.frame(f)
    return said, {k: _health_state(h) for k, h in w.watch.lines.items()}


@st.composite
def _health_frames(draw):
    from sniffer.codes import UART_FRAMING, UART_PARITY, Annotation

    codes = (UART_FRAMING.code, UART_PARITY.code, "modbus.crc.mismatch", "pair.orphan_response")
    out, t = [], 10**12
    for k in range(draw(st.integers(0, 300))):
        t += draw(st.sampled_from((0, 1, 10**6, 4 * 10**7, 10**8, 6 * 10**9)))
        f = Frame(k, t, t + 1, bytes(draw(st.integers(0, 90))), draw(st.sampled_from(("modbus-rtu", "noise", "x"))),
                  crc_ok=draw(st.sampled_from((True, False, None, False))))
        f.link = draw(st.sampled_from(("", "", "a", "b", None)))
        for code in draw(st.lists(st.sampled_from(codes), max_size=3)):
            f.annotations.append(Annotation(code, "error", "x", 0, 1))
        out.append(f)
    return out


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(_health_frames())
def test_line_warning_alike(frames):
    _need_hot()
    assert _warnings(True, frames) == _warnings(False, frames)


def test_line_warning_alike_on_a_breaking_line():
    """Bad runs of each kind between good ones: the warnings said are the same (and there are some)."""
    from sniffer.codes import UART_PARITY, Annotation

    _need_hot()
    rng, frames, t = random.Random(5), [], 10**9
    for kind in ("good", "crc", "good", "uart", "good", "noise", "good", "crc"):
        for _ in range(rng.randint(100, 500)):
            t += rng.randint(10**6, 3 * 10**7)
            f = Frame(len(frames), t, t + 1, bytes(rng.randint(1, 40)), "noise" if kind == "noise" else "modbus-rtu",
                      crc_ok=kind == "good" or (None if kind == "uart" else False))
            if kind == "uart":
                f.annotations.append(Annotation(UART_PARITY.code, "error", "x", 0, 1))
            f.link = rng.choice(("", "a"))
            frames.append(f)
    said, states = _warnings(True, frames)
    assert (said, states) == _warnings(False, frames)
    assert len(said) >= 4 and all("hint" in s for s in said)


def test_line_warning_odd_frames_take_the_reference():
    """A link that is not a string, a time past 2**61, raw that is not bytes: frame_py decides (alike)."""
    _need_hot()
    frames = [Frame(k, 10**9 + k * 10**7, 0, b"\0" * 9, "noise") for k in range(250)]
    frames[100].t_ns = 2**62
    frames[120].raw = bytearray(9)
    frames[130].link = 7
    assert _warnings(True, frames) == _warnings(False, frames)


# ------------------------------------------------------------------ the generic decoder: decoders/generic/decoder.py

def _generic_state(f: Frame) -> tuple:
    pts = f.points
    return (f.summary, [dict(p) for p in pts], type(f._points).__name__, f.writes, list(f.annotations), f.exception,
            f.model, f.fields)


def _generic_run(compiled: bool, pairs) -> tuple:
    """Decode each (request, response) with the compiled decoder or the reference; each frame's result and
    the shadow after all."""
    from decoders.base import UnitState
    from decoders.generic import GenericModbus

    class Reference(GenericModbus):  # a subclass: generic_fast is for GenericModbus itself only
        pass

    dec = GenericModbus() if compiled else Reference()
    assert (dec._compiled is not None) == compiled
    state, out = UnitState(1), []
    state.holding.update({k: k * 3 for k in range(0, 70000, 7)})
    for req, rsp in pairs:
        for f, peer in ((req, None), (rsp, req)):
            if f is None:
                continue
            f = _copy_frame(f)
            dec.decode(f, peer, state)
            out.append(_generic_state(f))
    return out, state.snapshot()


def _copy_frame(f: Frame) -> Frame:
    g = Frame(f.index, f.t_ns, f.t_end_ns, f.raw, f.protocol, f.unit, f.function, f.role_fits, f.crc_ok)
    g.adu, g.role = f.adu, f.role
    return g


def _gframe(adu: bytes, role: str, crc_ok) -> Frame:
    f = Frame(0, 0, 1, adu + b"\x00\x00", "modbus-rtu", adu[0] if adu else None, adu[1] if len(adu) > 1 else None,
              3, crc_ok)
    f.adu, f.role = adu, role
    return f


@st.composite
def _generic_pairs(draw):
    from sniffer.frame import REQUEST, RESPONSE, UNKNOWN

    pairs = []
    for _ in range(draw(st.integers(1, 8))):
        fc = draw(st.sampled_from((3, 3, 4, 6, 0x10, 0x10, 1, 5, 0x0F, 0x17, 0x83, 7)))
        unit = draw(st.sampled_from((1, 0, 1, 247)))
        a = draw(st.sampled_from((0, 100, 8448, 65535, 65500, 65534)))
        q = draw(st.sampled_from((1, 2, 10, 123, 124, 125, 126, 0)))
        k = draw(st.integers(0, 130)) if draw(st.booleans()) else q
        words = bytes(draw(st.binary(min_size=2 * min(k, 127), max_size=2 * min(k, 127))))
        if fc == 0x10:
            req = bytes([unit, fc]) + struct.pack(">HHB", a, q, draw(st.sampled_from((2 * k, 2 * k + 1, 2 * k)))
                                                  & 0xFF) + words
        elif fc == 6:
            req = bytes([unit, fc]) + struct.pack(">HH", a, q)
        else:
            req = bytes([unit, fc]) + struct.pack(">HH", a, q)
        if fc in (3, 4):
            rsp = bytes([unit, fc, draw(st.sampled_from((2 * k, 2 * k, 2 * k + 1))) & 0xFF]) + words
        elif fc == 0x10:
            rsp = bytes([unit, fc]) + struct.pack(">HH", draw(st.sampled_from((a, a, a + 1))) & 0xFFFF, q)
        else:
            rsp = req
        cut = draw(st.sampled_from((None, None, None, 1, 2, 3, 5, 6, 7)))
        if cut is not None:
            rsp = rsp[:cut] if draw(st.booleans()) else rsp
            req = req[:cut] if draw(st.booleans()) else req
        crc = st.sampled_from((True, True, True, False, None))
        rrole = draw(st.sampled_from((REQUEST, REQUEST, UNKNOWN)))
        r = _gframe(req, rrole, draw(crc)) if len(req) > 1 and draw(st.integers(0, 5)) else None
        s = _gframe(rsp, draw(st.sampled_from((RESPONSE, RESPONSE, UNKNOWN))), draw(crc))
        if len(rsp) > 1 and r is not None and draw(st.integers(0, 5)) == 0:
            s.function = draw(st.sampled_from((3, 0x10, 6)))  # a response to another function
        pairs.append((r, s))
    return pairs


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(_generic_pairs())
def test_generic_decoder_alike(pairs):
    _need_hot()
    assert _generic_run(True, pairs) == _generic_run(False, pairs)


def test_generic_decoder_compiled_for_the_common_frames():
    """The common frames do take the compiled path (it does not hand every one back)."""
    from decoders.base import UnitState
    from decoders.generic import GenericModbus
    from sniffer.frame import REQUEST, RESPONSE

    _need_hot()
    from decoders.generic.decoder import _HOT_CTX

    state = UnitState(1)
    req = _gframe(bytes([1, 3, 0x21, 0, 0, 2]), REQUEST, True)
    rsp = _gframe(bytes([1, 3, 4, 0, 7, 0, 9]), RESPONSE, True)
    assert HOT.generic_fast(req, None, state, _HOT_CTX) is None
    assert HOT.generic_fast(rsp, req, state, _HOT_CTX) is None
    assert rsp.summary == "holding[8448]=7 holding[8449]=9" and rsp.writes == [["holding", 8448, [7, 9]]]
    assert state.holding == {8448: 7, 8449: 9}
    w = _gframe(bytes([1, 0x10, 0, 5, 0, 2, 4, 0, 1, 0, 2]), REQUEST, True)
    assert HOT.generic_fast(w, None, state, _HOT_CTX) is None and w.summary == "write holding[5]=1 holding[6]=2"
    wr = _gframe(bytes([1, 0x10, 0, 5, 0, 2]), RESPONSE, True)
    assert HOT.generic_fast(wr, w, state, _HOT_CTX) is None and wr.summary == "wrote holding 5..6 (2)"
    assert state.holding[6] == 2 and GenericModbus()._compiled is HOT.generic_fast


def _standard_pairs(unit: int) -> list:
    """A well-formed (request, response) of each common function, as raw ADUs."""
    return [
        (bytes([unit, 3, 0x21, 0, 0, 2]), bytes([unit, 3, 4, 0, 7, 0, 9])),
        (bytes([unit, 4, 0, 0, 0, 1]), bytes([unit, 4, 2, 0xFF, 0xFE])),
        (bytes([unit, 6, 0, 9, 0x12, 0x34]), bytes([unit, 6, 0, 9, 0x12, 0x34])),
        (bytes([unit, 0x10, 0, 5, 0, 2, 4, 0, 1, 0, 2]), bytes([unit, 0x10, 0, 5, 0, 2])),
        (bytes([unit, 1, 0, 0, 0, 9]), bytes([unit, 1, 2, 0xFF, 0x01])),
    ]


@pytest.mark.parametrize("unit", [0, 1])
@pytest.mark.parametrize("req_crc", [True, False, None, "absent"])
@pytest.mark.parametrize("rsp_crc", [True, False, None])
@pytest.mark.parametrize("rsp_role", ["response", "unknown"])
def test_generic_decoder_alike_on_every_flag(unit, req_crc, rsp_crc, rsp_role):
    """Each common function's pair under every CRC verdict, role and broadcast: the same frames and shadow."""
    from sniffer.frame import REQUEST, RESPONSE, UNKNOWN

    _need_hot()
    role = RESPONSE if rsp_role == "response" else UNKNOWN
    pairs = [(None if req_crc == "absent" else _gframe(q, REQUEST, req_crc), _gframe(r, role, rsp_crc))
             for q, r in _standard_pairs(unit)]
    assert _generic_run(True, pairs) == _generic_run(False, pairs)
