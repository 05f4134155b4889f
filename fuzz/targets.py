"""The fuzz targets: every reader and parser of the sniffer, each a function of one input's bytes.

    one("mcap", data)          # runs the target on `data`; raises only for a bug (a crash to keep)

A file surface writes the bytes to a file of its kind and runs the command that reads it in-process
(sniffer.cli.main, as the console script runs it): main turns every error the project means (a
capture refused, a map, bus file, golden or status file that is wrong) into one line and an exit
code, so any exception that escapes it is a bug, and so is an exit code the command does not give.
The framers and the filter language are called directly (they are the hot path: more inputs a
second), with their own properties: every byte fed ends in exactly one frame; a filter is parsed or
refused with FilterError.

fuzz/run.py runs a target under atheris (coverage-guided, libFuzzer); fuzz/corpus/TARGET/ holds its
seeds (and every crash found, once fixed: tests/test_fuzz_targets.py replays the corpus in the fast
lane).
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CORPUS = Path(__file__).resolve().parent / "corpus"
WIZ = ROOT / "captures" / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv"
SMALL = CORPUS / "bytecsv" / "seed-wiz"  # 40 bytes of WIZ: what the golden seed was made from
FRAMES = ["010300000002C40B", "0103040001000290", "0104000A0002", "011000140002040001000A"]


@dataclass(frozen=True)
class FileTarget:
    """A file of kind `ext` read by `sniffer ARGV` (the file's path where ARGV says "{}"), exit codes `codes`."""

    ext: str
    argv: tuple[str, ...]
    codes: tuple[int, ...] = (0, 2)


FILE_TARGETS: dict[str, FileTarget] = {
    "mcap": FileTarget("mcap", ("replay", "{}", "--baud", "9600")),
    "pcap": FileTarget("pcap", ("replay", "{}", "--baud", "9600")),
    "pcapng": FileTarget("pcapng", ("replay", "{}", "--baud", "9600")),
    "bytecsv": FileTarget("csv", ("replay", "{}", "--baud", "9600")),
    "saleae": FileTarget("csv", ("replay", "{}", "--input-format", "saleae", "--baud", "9600")),
    "sigrok": FileTarget("sr", ("replay", "{}", "--rx", "0", "--baud", "9600")),
    "bus": FileTarget("toml", ("replay", str(WIZ), "--bus", "{}")),
    "map_toml": FileTarget("toml", ("decode", *FRAMES, "--model-file", "{}", "--device", "1=fuzz")),
    "map_csv": FileTarget("csv", ("decode", *FRAMES, "--model-file", "{}", "--device", "1=fuzz")),
    # a Home Assistant map's model is named by its file: input.yaml
    "map_yaml": FileTarget("yaml", ("decode", *FRAMES, "--model-file", "{}", "--device", "1=input")),
    "golden": FileTarget("txt", ("check", str(SMALL), "--baud", "9600", "--golden", "{}"), (0, 1, 2)),
    # the capture is the small one (a tds-v8 capture took seconds an input): the --params reader is the target
    "params": FileTarget("csv", ("diagnose", str(SMALL), "--baud", "9600", "--params", "{}", "--format", "json")),
    "status": FileTarget("json", ("status", "{}", "--json"), (0, 1, 2)),
}


class Unexpected(AssertionError):
    """A target's input gave what no input may: an exit code the command does not give, a byte lost."""


_WORK: str | None = None


def _path(ext: str) -> str:
    global _WORK
    if _WORK is None:
        _WORK = tempfile.mkdtemp(prefix="sniffer-fuzz-")
    return os.path.join(_WORK, f"input.{ext}")


def run_file(name: str, data: bytes) -> int:
    """The file target `name` on `data`: its exit code (an exception escaping main is a bug: raised)."""
    from sniffer.cli import main

    t = FILE_TARGETS[name]
    path = _path(t.ext)
    with open(path, "wb") as f:
        f.write(data)
    argv = [a.replace("{}", path) for a in t.argv]
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            rc = main(argv)
        except SystemExit as e:  # argparse's --help and the like: not reached by a file's bytes, but not a crash
            rc = e.code if isinstance(e.code, int) else 2
    if rc not in t.codes:
        raise Unexpected(f"{name}: exit {rc}, not one of {t.codes}: {out.getvalue()[-500:]}")
    if "Traceback" in out.getvalue():
        raise Unexpected(f"{name}: a traceback was printed: {out.getvalue()[-1500:]}")
    return rc


def run_framers(data: bytes) -> None:
    """The first byte picks the read sizes and the silences between reads; the rest is the line.  Every framer
    gets the same reads; every byte fed comes out in exactly one frame, in order."""
    from sniffer.events import Chunk
    from sniffer.framing import AsciiFramer, PdAsciiFramer, PdRtuFramer, RtuFramer
    from sniffer.line import LineSettings

    if not data:
        return
    shape, line = data[0], data[1:]
    size = 1 + (shape & 0x1F)  # 1..32 bytes a read
    gap_ns = (shape >> 5) * 2_000_000  # 0..14 ms between reads: within and past the 3.5 character silence
    settings = LineSettings(9600, "N", 1, 8)
    for framer_class in (RtuFramer, AsciiFramer, PdRtuFramer, PdAsciiFramer):
        framer = framer_class(settings)
        frames = []
        t = 1_000_000
        for i in range(0, len(line), size):
            frames += framer.feed(Chunk(t, line[i:i + size]))
            t += gap_ns + size * 1_042_000
        frames += framer.flush()
        out = b"".join(f.raw for f in frames)
        if out != line:
            raise Unexpected(f"{framer_class.__name__}: {len(line)} bytes fed, {len(out)} came out in frames"
                             f"{' (reordered)' if len(out) == len(line) else ''}")


def run_hot(data: bytes) -> None:
    """The compiled path (sniffer._hot) against the pure-Python one on the same bytes: the RTU framer on reads
    shaped by the first byte (as `framers`), the bytes as a /raw message, as the records of an MCAP chunk and
    as a line's frames through the line-settings warning's window (4 bytes a frame), and as a request and a
    response through the generic decoder.  Any difference is a crash.  The other targets run whichever
    path the process loaded (the compiled one unless SNIFFER_PURE=1); this one runs both.  Without the
    extension built it checks nothing."""
    from sniffer.hot import HOT

    if HOT is None or not data:
        return
    import struct
    import zlib

    from mcap.records import Channel

    from sniffer.events import Chunk
    from sniffer.formats.mcap.format import decode_event, decode_event_py
    from sniffer.formats.mcap.scan import _walk_chunk
    from sniffer.frame import Frame
    from sniffer.framing.rtu import RtuFramer
    from sniffer.line import LineSettings

    class Pure(RtuFramer):
        _compiled_fast = None

    shape, line = data[0], data[1:]
    size = 1 + (shape & 0x1F)
    gap_ns = (shape >> 5) * 2_000_000
    settings = LineSettings(9600, "N", 1, 8)
    got = []
    for framer_class in (RtuFramer, Pure):
        framer, frames, t = framer_class(settings), [], 1_000_000
        for i in range(0, len(line), size):
            frames += framer.feed(Chunk(t, line[i:i + size]))
            t += gap_ns + size * 1_042_000
        frames += framer.flush()
        got.append([tuple(repr(getattr(f, k)) for k in Frame.__slots__ if k not in ("peer", "encoded", "_points"))
                    for f in frames])
    if got[0] != got[1]:
        raise Unexpected("the RTU framer's frames differ between the compiled and the pure path")

    def outcome(fn, *args):
        try:
            return "ok", repr(fn(*args))
        except Exception as e:  # noqa: BLE001 - the same exception on both paths is what is compared
            return "error", type(e).__name__, str(e)

    if outcome(decode_event, line) != outcome(decode_event_py, line):
        raise Unexpected("a /raw message decodes differently on the compiled and the pure path")
    known = {1: Channel(id=1, schema_id=1, topic="/raw", message_encoding="json", metadata={})}
    body = (struct.pack("<QQQI", 0, 0, len(line), zlib.crc32(line)) + struct.pack("<I", 0)
            + struct.pack("<Q", len(line)) + line)
    skip = (lambda topic: topic != "/raw")  # noqa: E731
    if outcome(_walk_chunk, body, dict(known), skip) != outcome(_walk_chunk, body, dict(known), skip, None):
        raise Unexpected("an MCAP chunk's records differ between the compiled and the pure path")
    _health_alike(shape, line)
    _generic_alike(shape, line)


def _generic_alike(shape: int, line: bytes) -> None:
    """GenericModbus (generic_fast) and a subclass of it (decode_py only) on the bytes cut in two ADUs, a
    request and its response, CRC verdicts and roles from `shape`: the same frames and register shadow."""
    from decoders.base import UnitState
    from decoders.generic import GenericModbus
    from sniffer.frame import REQUEST, RESPONSE, UNKNOWN, Frame

    class Reference(GenericModbus):
        pass

    cut = 2 + (shape & 0x0F)
    verdicts = (True, False, None, True)
    got = []
    for dec in (GenericModbus(), Reference()):
        state, out, frames = UnitState(1), [], []
        for adu, role, crc in ((line[:cut], REQUEST, verdicts[(shape >> 4) & 3]),
                               (line[cut:], RESPONSE if shape & 0x40 else UNKNOWN, verdicts[shape >> 6])):
            f = Frame(0, 0, 1, adu + b"\0\0", "modbus-rtu", adu[0] if adu else None,
                      adu[1] if len(adu) > 1 else None, 3, crc)
            f.adu, f.role = adu, role
            dec.decode(f, frames[-1] if frames else None, state)
            frames.append(f)
            out.append((f.summary, [dict(p) for p in f.points], f.writes, list(f.annotations), f.exception))
        got.append((out, state.snapshot()))
    if got[0] != got[1]:
        raise Unexpected("the generic decoder's frames differ between the compiled and the pure path")


def _health_alike(shape: int, line: bytes) -> None:
    """LineHealth (C) and LineHealthPy on the same frames: 4 bytes each (time step, size, badness, add or
    advance); the window size from `shape`.  The state after every step must be the same."""
    from sniffer.analysis.linehealth import LineHealth, LineHealthPy

    kw = {"max_frames": 1 + (shape & 0x3F) * 4, "window_s": (shape >> 6) * 2.0}
    states = []
    for h in (LineHealth("a", **kw), LineHealthPy("a", **kw)):
        t, out = 10**12, []
        for i in range(0, len(line) - 3, 4):
            dt, size, bad, op = line[i:i + 4]
            t += dt * dt * 100_000
            b = (None, None, 0, 1, 2)[bad % 5]
            out.append(h.add(t, size, b) if op & 1 else h.advance(t))
            out.append((h.frames, h.nbytes, h.bad, h.bad_bytes, list(h.kinds), h.broken, h.warnings, h.window()))
        states.append(out)
    if states[0] != states[1]:
        raise Unexpected("the line health's window differs between the compiled and the pure path")


def run_filter(data: bytes) -> None:
    from sniffer.filterlang.parser import FilterError, parse

    text = data.decode("utf-8", "replace")
    try:
        parse(text)
    except FilterError:
        pass


TARGETS: dict[str, Callable[[bytes], object]] = {
    **{name: (lambda data, name=name: run_file(name, data)) for name in FILE_TARGETS},
    "framers": run_framers,
    "filter": run_filter,
    "hot": run_hot,
}


def one(name: str, data: bytes):
    return TARGETS[name](data)
