"""Throughput and memory of the sniffer pipeline, with pymodbus (and sigrok-cli) as peers.

    .venv/bin/python benchmarks/bench_pipeline.py [--frames N] [--quick] [--profile]

1. Generate (not timed) a simulated capture of at least N frames: the `stress`
   scenario (4 units, 7 function codes, reads up to 125 registers) with a few
   errors added (CRC hits, exceptions, lost answers, late answers, noise), at
   115200 8N1, seen through a USB adapter (`usb_chunks`: per-read chunks that
   glue and split frames).  The chunks go to a compact file in a temporary
   folder; the ground truth (every wire frame but noise) to another.
2. Measure, each in a fresh subprocess so one run's peak RSS does not hide
   another's, on one core (a single process, one thread):
     a. split + CRC + pair: RtuFramer.feed + Pairer.push, no decode, no sinks;
     b. the full pipeline to JSONL (Pipeline + default_registry + JsonlSink
        on /dev/null);
     c. peak RSS of (b) fed by a generator streaming the file, for N/4 and N
        frames: flat memory means the two are the same;
   plus how many frames the framer recovers, byte for byte, against the truth.
3. Peers: pymodbus' RTU framer fed the same byte stream in the same read-sized
   pieces (as its transport does), and its best case (frames pre-split,
   direction known); sigrok-cli if installed (apt-get install sigrok-cli), on a
   given .sr capture or on the capture's first 2,000 frames as logic samples.

Figures are printed, nothing is asserted: tests never assert wall-clock times.
`--profile` instead runs (b) under cProfile and prints the top functions.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import gc
import json
import os
import platform
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from sniffer.events import CaptureInfo, Chunk
from sniffer.line import LineSettings

LINE = LineSettings(115200, "N", 1)
SEED = 7
TARGET_SPLIT = 300_000  # frames/s
TARGET_FULL = 80_000  # frames/s
FLAT_TOLERANCE = 0.10  # N-frame peak RSS within 10 % of the N/4 one counts as flat
SIGROK_ELSEWHERE = "about 460 frames/s measured elsewhere"
_CHUNK = struct.Struct("<qI")  # t_ns, length; then the bytes
_TRUTH = struct.Struct("<BBH")  # direction (0 request, 1 response), crc valid, length; then the bytes


# ------------------------------------------------------------ the capture
MIXES = ("drive", "stress")
MIX = os.environ.get("BENCH_MIX", "drive")

# What a PLC polls on a drive link: monitor and control blocks of a few registers,
# setpoint and command writes, some coils.  `stress` instead reads 125-register
# blocks (255-byte responses), the heaviest legal traffic per frame.
DRIVE_POLLS = (
    ("monitor", 0x03, 0x2100, 8),
    ("control", 0x03, 0x2000, 4),
    ("inputs", 0x04, 0x0000, 6),
    ("coils", 0x01, 0x0000, 16),
    ("setpoint", 0x10, 0x2000, 2),
    ("command", 0x06, 0x2001, 1),
    ("relay", 0x05, 0x0003, 1),
)


def bench_scenario():
    """`stress` (or its drive-poll mix) with a few errors, built with dataclasses.replace."""
    from sniffer.simulator import PollSpec, UnitSpec, get_scenario

    stress = get_scenario("stress")
    if MIX == "drive":
        stress = dataclasses.replace(
            stress, polls=tuple(PollSpec(fc, addr, qty) for _name, fc, addr, qty in DRIVE_POLLS))
    ta = (2.0, 3.0)
    return dataclasses.replace(
        stress,
        name=f"{MIX}+errors",
        units=(
            UnitSpec(1, turnaround_chars=ta, corrupt_prob=0.002, busy_prob=0.003),
            UnitSpec(2, turnaround_chars=ta, no_answer_prob=0.002),
            UnitSpec(3, turnaround_chars=ta, slow_prob=0.01),
            UnitSpec(4, turnaround_chars=ta, corrupt_prob=0.001),
        ),
        # outside the drive map: exception 02 from every unit now and then
        polls=stress.polls + (PollSpec(0x03, 0x3000, 2, every=40),),
        request_corrupt_prob=0.001,
        noise_prob=0.002,
    )


def generate(n: int, folder: Path) -> dict:
    """Write chunks.bin, truth.bin and meta.json for a capture of at least n frames."""
    from sniffer.simulator import KIND_CORRUPTED, KIND_NOISE, KIND_REQUEST, simulate, usb_chunks

    sc = bench_scenario()
    t_start = time.perf_counter()
    probe_s = 20.0
    rate = sum(1 for f in simulate(sc, LINE, probe_s, SEED) if f.kind != KIND_NOISE) / probe_s
    duration = n / rate * 1.02 + 1.0  # frames per simulated second is steady: 2 % margin
    kinds: Counter = Counter()
    pulled = 0
    truth_f = open(folder / "truth.bin", "wb")

    def frames():
        nonlocal pulled
        for wf in simulate(sc, LINE, duration, SEED):
            kinds[wf.kind] += 1
            if wf.kind != KIND_NOISE:
                pulled += 1
                is_req = wf.role in (KIND_REQUEST, "broadcast")
                truth_f.write(_TRUTH.pack(0 if is_req else 1, wf.kind != KIND_CORRUPTED, len(wf.raw)))
                truth_f.write(wf.raw)
            yield wf

    n_chunks = n_bytes = 0
    quarter_chunks = None
    with open(folder / "chunks.bin", "wb") as out:
        for ch in usb_chunks(frames(), seed=SEED):
            out.write(_CHUNK.pack(ch.t_ns, len(ch.data)))
            out.write(ch.data)
            n_chunks += 1
            n_bytes += len(ch.data)
            if quarter_chunks is None and pulled >= n // 4:
                quarter_chunks = n_chunks
    truth_f.close()
    meta = {
        "scenario": sc.name, "line": LINE.label(), "seed": SEED, "sim_duration_s": round(duration, 1),
        "chunks": n_chunks, "bytes": n_bytes, "quarter_chunks": quarter_chunks or n_chunks,
        "truth_frames": pulled, "truth_kinds": dict(kinds),
        "gen_s": round(time.perf_counter() - t_start, 1),
    }
    (folder / "meta.json").write_text(json.dumps(meta))
    return meta


def read_chunks(path: Path, limit: int | None = None):
    """Stream the chunk file back as Chunks (per read: no per-byte times)."""
    hdr = _CHUNK.size
    unpack = _CHUNK.unpack
    with open(path, "rb", buffering=1 << 20) as f:
        read = f.read
        i = 0
        while limit is None or i < limit:
            h = read(hdr)
            if len(h) < hdr:
                return
            t, n = unpack(h)
            yield Chunk(t, read(n), None, (), "")
            i += 1


def read_truth(path: Path):
    """[(direction, crc_valid, raw)] for every wire frame but noise."""
    data = Path(path).read_bytes()
    out = []
    i, size, unpack = 0, _TRUTH.size, _TRUTH.unpack_from
    while i < len(data):
        d, v, n = unpack(data, i)
        i += size
        out.append((d, v, data[i : i + n]))
        i += n
    return out


# ------------------------------------------------------- child measurements
def _rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


def _info() -> CaptureInfo:
    return CaptureInfo(source="bench", baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits,
                       time_source="read", t0_ns=0)


def _split_once(chunks) -> tuple[int, float]:
    from sniffer.framing.rtu import RtuFramer
    from sniffer.capture.pairer import Pairer

    gc.collect()
    t0 = time.perf_counter()
    framer, pairer = RtuFramer(LINE), Pairer()
    feed, push = framer.feed, pairer.push
    n = 0
    for ch in chunks:
        for f in feed(ch):
            n += len(push(f))
    for f in framer.flush():
        n += len(push(f))
    n += len(pairer.flush())
    return n, time.perf_counter() - t0


def child_split(folder: Path, _limit, repeat: int = 1) -> dict:
    chunks = list(read_chunks(folder / "chunks.bin"))
    n_bytes = sum(len(c.data) for c in chunks)
    rss_loaded = _rss_mib()
    runs = [_split_once(chunks) for _ in range(repeat)]
    times = [dt for _n, dt in runs]
    return {"frames": runs[0][0], "bytes": n_bytes, "seconds": min(times), "times": times,
            "rss_loaded": rss_loaded, "rss_peak": _rss_mib()}


def _full_once(events):
    from decoders.registry import default_registry
    from sniffer.capture.pipeline import Pipeline
    from sniffer.formats.jsonl import JsonlSink

    registry = default_registry()  # built once at start-up: not part of the per-frame cost
    gc.collect()
    t0 = time.perf_counter()
    with open(os.devnull, "wb") as devnull:
        p = Pipeline(_info(), LINE, registry, [JsonlSink(devnull)])
        feed = p.feed
        for ev in events:
            feed(ev)
        p.finish()
    return p, time.perf_counter() - t0


def child_full(folder: Path, limit, repeat: int = 1) -> dict:
    chunks = list(read_chunks(folder / "chunks.bin", limit))
    rss_loaded = _rss_mib()
    runs = [_full_once(chunks) for _ in range(repeat)]
    p = runs[0][0]
    times = [dt for _p, dt in runs]
    return {"frames": p.frames_out, "bytes": p.bytes_in, "seconds": min(times), "times": times,
            "rss_loaded": rss_loaded, "rss_peak": _rss_mib()}


def child_stream(folder: Path, limit, _repeat: int = 1) -> dict:
    """(b) fed by a generator reading the file: nothing but the pipeline grows with the capture."""
    rss_start = _rss_mib()
    p, dt = _full_once(read_chunks(folder / "chunks.bin", limit))
    return {"frames": p.frames_out, "bytes": p.bytes_in, "seconds": dt, "rss_loaded": rss_start,
            "rss_peak": _rss_mib()}


def child_verify(folder: Path, _limit, _repeat: int = 1) -> dict:
    """Our frames against the truth, byte for byte, and the pairer's roles against the sender."""
    from sniffer.framing.rtu import RtuFramer
    from sniffer.capture.pairer import Pairer

    truth = read_truth(folder / "truth.bin")
    want = Counter(raw for _d, _v, raw in truth)
    want_valid = Counter(raw for _d, v, raw in truth if v)
    framer, pairer = RtuFramer(LINE), Pairer()
    ours: list[tuple[str, bytes, bool]] = []
    noise_frames = noise_bytes = 0

    def take(frames):
        nonlocal noise_frames, noise_bytes
        for f in frames:
            if f.protocol == "noise":
                noise_frames += 1
                noise_bytes += len(f.raw)
            else:
                ours.append((f.role, f.raw, bool(f.crc_ok)))

    for ch in read_chunks(folder / "chunks.bin"):
        for f in framer.feed(ch):
            take(pairer.push(f))
    for f in framer.flush():
        take(pairer.push(f))
    take(pairer.flush())
    got = Counter(raw for _r, raw, _ok in ours)
    # roles: walk both (ordered) lists; a frame of ours matches the next equal truth frame a few ahead
    roles = ("request", "response")
    i = aligned = role_ok = 0
    for role, raw, _ok in ours:
        for j in range(i, min(i + 8, len(truth))):
            if truth[j][2] == raw:
                aligned += 1
                role_ok += role == roles[truth[j][0]]
                i = j + 1
                break
    return {
        "truth": len(truth), "truth_valid": sum(want_valid.values()), "ours": len(ours),
        "matched": sum((want & got).values()), "matched_valid": sum((want_valid & got).values()),
        "crc_bad": sum(not ok for _r, _raw, ok in ours), "noise_frames": noise_frames,
        "noise_bytes": noise_bytes, "aligned": aligned, "role_ok": role_ok,
    }


def _quiet_pymodbus() -> None:
    import logging

    # with no handler configured, logging's last resort prints every "Unable to decode" warning
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL + 1)


def child_pymodbus_stream(folder: Path, _limit, _repeat: int = 1) -> dict:
    """The mixed stream through pymodbus' RTU framer, as its transport feeds it."""
    from pymodbus.exceptions import ModbusIOException
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU

    from sniffer.framing.crc import crc_bytes

    _quiet_pymodbus()

    class Capturing(FramerRTU):
        """FramerRTU that remembers the ADU of the frame it decoded (to check it against the truth)."""

        last = b""

        def decode(self, data):
            r = super().decode(data)
            if r[3]:
                self.last = bytes((r[1],)) + r[3]
            return r

    truth = read_truth(folder / "truth.bin")
    want = Counter(raw for _d, _v, raw in truth)
    chunks = list(read_chunks(folder / "chunks.bin"))
    out = {"truth": len(truth)}
    got_all: Counter = Counter()
    t0 = time.perf_counter()
    for side, is_server in (("server", True), ("client", False)):
        framer = Capturing(DecodePDU(is_server=is_server))
        max_buffer = 516  # pymodbus.transport.ModbusProtocol.max_buffer_size
        buf = b""
        pdus = overflows = errors = 0
        got: Counter = Counter()
        for ch in chunks:  # transport.datagram_received + transaction.callback_data
            buf += ch.data
            if len(buf) > max_buffer:
                buf = b""
                overflows += 1
                continue
            try:
                used, pdu = framer.handleFrame(buf, 0, 0)
            except ModbusIOException:
                buf = b""
                errors += 1
                continue
            buf = buf[used:]
            if pdu is not None:
                pdus += 1
                adu = framer.last + crc_bytes(framer.last)
                got[adu] += 1
        got_all += got
        out[side] = {"pdus": pdus, "matched": sum((want & got).values()), "overflows": overflows,
                     "errors": errors}
    out["matched"] = sum((want & got_all).values())
    out["seconds"] = time.perf_counter() - t0
    return out


def child_pymodbus_split(folder: Path, limit, repeat: int = 1) -> dict:
    """pymodbus' best case: frames already split, requests to a server-side decoder, responses to a client-side one."""
    from pymodbus.exceptions import ModbusIOException
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU

    _quiet_pymodbus()
    frames = [(d, raw) for d, _v, raw in read_truth(folder / "truth.bin")][:limit]
    n_bytes = sum(len(raw) for _d, raw in frames)
    handle = (FramerRTU(DecodePDU(is_server=True)).handleFrame, FramerRTU(DecodePDU(is_server=False)).handleFrame)
    times = []
    for _ in range(repeat):
        gc.collect()
        decoded = errors = 0
        t0 = time.perf_counter()
        for d, raw in frames:
            try:
                if handle[d](raw, 0, 0)[1] is not None:
                    decoded += 1
            except ModbusIOException:
                errors += 1
        times.append(time.perf_counter() - t0)
    return {"frames": len(frames), "bytes": n_bytes, "decoded": decoded, "errors": errors,
            "seconds": min(times), "times": times}


def child_profile(folder: Path, _limit, _repeat: int = 1) -> dict:
    """(b) under cProfile: the chunks are loaded first, only the pipeline run is profiled."""
    import cProfile
    import pstats

    chunks = list(read_chunks(folder / "chunks.bin"))
    prof = cProfile.Profile()
    p, dt = prof.runcall(_full_once, chunks)
    st = pstats.Stats(prof)
    total = max(v[3] for v in st.stats.values())  # cumulative time of the outermost call
    rows = [{"fn": f"{Path(file).name}:{line}({fn})", "calls": nc, "cum_pct": 100 * ct / total,
             "tot_pct": 100 * tt / total}
            for (file, line, fn), (_cc, nc, tt, ct, _callers) in st.stats.items()]
    rows.sort(key=lambda r: -r["cum_pct"])
    return {"frames": p.frames_out, "profile": rows[:40], "profile_total_s": total}


CHILDREN = {
    "split": child_split, "full": child_full, "stream": child_stream, "verify": child_verify,
    "pymodbus-stream": child_pymodbus_stream, "pymodbus-split": child_pymodbus_split,
    "profile": child_profile,
}


def instructions(kind: str, folder: Path, limit: int) -> int:
    """Instructions (valgrind's Ir) of one child run: deterministic, whatever else the machine is doing."""
    import re

    cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable,
           str(Path(__file__).resolve()), "--child", kind, "--dir", str(folder), "--repeat", "1", "--limit", str(limit)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    m = re.search(r"Collected : (\d+)", r.stderr)
    if r.returncode != 0 or m is None:
        sys.stderr.write(r.stderr[-2000:])
        raise SystemExit(f"bench: valgrind run of {kind!r} failed ({r.returncode})")
    return int(m.group(1))


def per_frame_instructions(folder: Path, frames: int, chunks: int) -> dict:
    """Ir per frame of (b) and of pymodbus' best case: a run of N minus a run of none, over N.

    (b) is limited by chunks read, pymodbus by frames; both children load their input the same way
    with and without the limit, so start-up, imports and the registry cancel out.
    """
    out = {}
    full_n, full_0 = instructions("full", folder, chunks), instructions("full", folder, 0)
    n = run_child("full", folder, chunks)["frames"]
    out["ours"] = (full_n - full_0) / n
    py_n, py_0 = instructions("pymodbus-split", folder, frames), instructions("pymodbus-split", folder, 0)
    out["pymodbus"] = (py_n - py_0) / frames
    out["frames_ours"], out["frames_pymodbus"] = n, frames
    return out


def run_child(kind: str, folder: Path, limit: int | None = None, repeat: int = 1) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, "--dir", str(folder),
           "--repeat", str(repeat)]
    if limit is not None:
        cmd += ["--limit", str(limit)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit(f"bench: child {kind!r} failed ({r.returncode})")
    return json.loads(r.stdout.strip().splitlines()[-1])


# ----------------------------------------------------------------- sigrok
SIGROK_FRAMES = 2000  # sigrok-cli decodes logic samples, not bytes: a slice of the capture is enough
SIGROK_RATE = 1_000_000  # samples/s: 8.7 samples a bit at 115200 baud
REFCAPTURES = Path(__file__).resolve().parent.parent / "captures" / "refcaptures" / "sigrok"


def logic_capture(truth, rate: int = SIGROK_RATE) -> bytes:
    """Wire frames as a 2-channel logic capture, one byte a sample: bit 0 the master's line
    (requests), bit 1 the slaves' (responses), idle high, 3.5 characters between frames."""
    spb = rate / LINE.baud
    par = {"N": None, "E": 0, "O": 1}[LINE.parity]
    out = bytearray()
    t = 0.0
    idle = 0b11

    def hold(end: float, level: int) -> None:
        n = int(round(end)) - len(out)
        if n > 0:
            out.extend(bytes((level,)) * n)

    for direction, _valid, raw in truth:
        t += spb * 10 * 3.5
        hold(t, idle)
        low = idle & ~(1 << direction)
        for byte in raw:
            bits = [0] + [(byte >> i) & 1 for i in range(8)]
            if par is not None:
                bits.append((bin(byte).count("1") + par) & 1)
            bits += [1] * LINE.stopbits
            for bit in bits:
                t += spb
                hold(t, idle if bit else low)
    hold(t + spb * 40, idle)
    return bytes(out)


def sigrok_peer(folder: Path, capture: str | None) -> str:
    """sigrok-cli's uart + modbus decoders: on a given .sr capture, or on the first frames of ours as logic samples."""
    exe = shutil.which("sigrok-cli")
    if not exe:
        return f"sigrok-cli not installed (apt-get install sigrok-cli; {SIGROK_ELSEWHERE})"
    if capture:
        ref = REFCAPTURES / (Path(capture).stem + ".json")
        if not ref.exists():
            return f"no {ref.name} in captures/refcaptures/sigrok: cannot choose decoder options"
        meta = json.loads(ref.read_text())
        frames = meta["frames_csv_derived_by_us"]["frames"]
        cmd = [exe, "-i", capture, "-P", meta["sigrok_cli"]["modbus_pd_spec"], "-A", "modbus"]
        what = f"{frames} frames of {Path(capture).name}"
    else:
        truth = read_truth(folder / "truth.bin")[:SIGROK_FRAMES]
        path = folder / "logic.bin"
        path.write_bytes(logic_capture(truth))
        frames = len(truth)
        parity = {"N": "none", "E": "even", "O": "odd"}[LINE.parity]
        spec = (f"uart:rx=0:tx=1:baudrate={LINE.baud}:parity={parity}:stop_bits={LINE.stopbits},"
                f"modbus:scchannel=TX:cschannel=RX")
        cmd = [exe, "-I", f"binary:numchannels=2:samplerate={SIGROK_RATE}", "-i", str(path), "-P", spec,
               "-A", "modbus"]
        what = (f"the first {frames:,} frames of this capture as 2-channel logic samples at "
                f"{SIGROK_RATE / 1e6:g} MS/s")
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        return f"sigrok-cli failed: {r.stderr.strip()[:200]}"
    good = r.stdout.count("CRC correct")
    return f"{frames / dt:,.0f} frames/s ({what}, {good:,} CRC correct, {dt:.2f} s)"


# ------------------------------------------------------------------ report
def revision() -> str:
    """The sniffer's git commit, and whether the working tree had changes (the code measured)."""
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "sniffer", "decoders"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown revision"
    return f"commit {head}" + (" + uncommitted changes in sniffer/ or decoders/" if dirty else "")


def machine() -> str:
    cpu = "unknown cpu"
    try:
        for ln in Path("/proc/cpuinfo").read_text().splitlines():
            if ln.startswith("model name"):
                cpu = ln.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (f"{cpu}, {os.cpu_count()} CPUs; Python {platform.python_version()} ({platform.machine()}); "
            f"{platform.system()} {platform.release()}; load average {load}")


def _k(x: float) -> str:
    return f"{x / 1000:,.1f}k"


def _runs(r: dict) -> str:
    t = r["times"]
    if len(t) == 1:
        return f"{t[0]:.2f} s"
    return f"best of {len(t)}: {min(t):.2f} s, worst {max(t):.2f} s"


def _pct(a: int, b: int) -> str:
    return f"{100 * a / b:.2f} %" if b else "-"


def report(meta: dict, res: dict, sigrok: str, n_req: int) -> None:
    sp, fu, ve = res["split"], res["full"], res["verify"]
    pst, psp = res["pymodbus-stream"], res["pymodbus-split"]
    q, s = res["stream_q"], res["stream_n"]
    mb = meta["bytes"] / 1e6
    print()
    print(f"capture: scenario {meta['scenario']} at {meta['line']}, seed {meta['seed']}, "
          f"{meta['sim_duration_s']:,} s of bus time, generated in {meta['gen_s']} s (not timed)")
    kinds = ", ".join(f"{k} {v:,}" for k, v in sorted(meta["truth_kinds"].items(), key=lambda kv: -kv[1]))
    print(f"  wire frames: {kinds}")
    print(f"  {meta['truth_frames']:,} frames (noise excluded; asked for {n_req:,}), {mb:.2f} MB, "
          f"{meta['chunks']:,} USB reads ({meta['bytes'] / meta['chunks']:.1f} bytes/read)")
    print(f"ours, framer+pairer: {ve['ours']:,} frames, {ve['matched']:,} byte-exact in the truth "
          f"({ve['matched_valid']:,} of {ve['truth_valid']:,} CRC-valid ones), {ve['crc_bad']:,} CRC-bad, "
          f"{ve['noise_frames']:,} noise frames ({ve['noise_bytes']:,} bytes)")
    print(f"  pairer: role (request/response) as sent for {ve['role_ok']:,} of {ve['aligned']:,} frames "
          f"aligned with the truth")
    for side, what in (("server", "requests"), ("client", "responses")):
        r = pst[side]
        print(f"pymodbus stream, {side}-side decoder: {r['pdus']:,} {what} decoded ({r['matched']:,} byte-exact "
              f"in the truth), {r['overflows']:,} buffer resets (> 516 bytes), "
              f"{r['errors']:,} ModbusIOException (buffer dropped)")
    print(f"pymodbus pre-split: {psp['decoded']:,} of {psp['frames']:,} frames decoded, "
          f"{psp['errors']:,} ModbusIOException")

    split_fps = sp["frames"] / sp["seconds"]
    full_fps = fu["frames"] / fu["seconds"]
    py_fps = psp["frames"] / psp["seconds"]
    growth = (s["rss_peak"] - q["rss_peak"]) / q["rss_peak"]
    flat = "flat" if growth <= FLAT_TOLERANCE else "GROWS"

    def ok(v, t):
        return "ok" if v >= t else "BELOW"

    rows = [
        ("metric", "ours", "peer", "target"),
        ("split+CRC+pair, frames/s", f"{_k(split_fps)} ({_runs(sp)})", "-",
         f">= {_k(TARGET_SPLIT)}: {ok(split_fps, TARGET_SPLIT)}"),
        ("split+CRC+pair, MB/s of wire", f"{sp['bytes'] / 1e6 / sp['seconds']:.2f}", "-", "-"),
        ("full decode -> JSONL, frames/s", f"{_k(full_fps)} ({_runs(fu)})",
         f"pymodbus pre-split, direction known: {_k(py_fps)} ({_runs(psp)})",
         f">= {_k(TARGET_FULL)}: {ok(full_fps, TARGET_FULL)}"),
        ("full decode -> JSONL, MB/s of wire", f"{fu['bytes'] / 1e6 / fu['seconds']:.2f}",
         f"pymodbus: {psp['bytes'] / 1e6 / psp['seconds']:.2f}", "-"),
        ("frames recovered from the stream",
         f"{ve['matched']:,} / {ve['truth']:,} ({_pct(ve['matched'], ve['truth'])})",
         f"pymodbus: {pst['matched']:,} ({_pct(pst['matched'], pst['truth'])})", "all"),
        ("peak RSS (b) streamed, N/4 frames", f"{q['rss_peak']:.1f} MiB ({q['frames']:,} frames)", "-", "-"),
        ("peak RSS (b) streamed, N frames", f"{s['rss_peak']:.1f} MiB ({s['frames']:,} frames)", "-",
         f"flat: {flat} ({100 * growth:+.1f} %)"),
        ("peak RSS (b), chunks held in a list", f"{fu['rss_peak']:.1f} MiB (list alone {fu['rss_loaded']:.1f})",
         "-", "-"),
        ("streamed (b), frames/s", f"{_k(s['frames'] / s['seconds'])}", "-", "-"),
        ("sigrok-cli", "-", sigrok, "-"),
    ]
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    print()
    for i, r in enumerate(rows):
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
        if i == 0:
            print("  ".join("-" * w for w in widths))
    print()
    print(f"ours / pymodbus best case: (a) {split_fps / py_fps:.2f}x, (b) {full_fps / py_fps:.2f}x "
          f"(a yardstick that moves less than frames/s when the machine is shared)")
    print(f"machine: {machine()}")


def print_profile(res: dict, top: int) -> None:
    print(f"\ncProfile of (b), {res['frames']:,} frames, {res['profile_total_s']:.2f} s under the profiler")
    print(f"{'cum %':>6} {'own %':>6} {'calls':>10}  function")
    for r in res["profile"][:top]:
        print(f"{r['cum_pct']:6.1f} {r['tot_pct']:6.1f} {r['calls']:10,}  {r['fn']}")


def main(argv=None) -> int:
    global MIX
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=None, help="frames in the capture (default 1,000,000)")
    ap.add_argument("--quick", action="store_true", help="50,000 frames: a check that everything runs")
    ap.add_argument("--mix", choices=MIXES, default=os.environ.get("BENCH_MIX", "drive"),
                    help="drive: typical PLC-drive polls (default); stress: 125-register reads")
    ap.add_argument("--profile", action="store_true", help="cProfile the full pipeline (default 100,000 frames)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="timed runs of (a), (b) and pymodbus' best case; the best is reported (default 3)")
    ap.add_argument("--sigrok-capture", help="a sigrok .sr capture to time sigrok-cli on (if installed)")
    ap.add_argument("--instructions", action="store_true",
                    help="valgrind instruction counts per frame of (b) and pymodbus' best case (20,000 frames): "
                         "a ratio that does not move when the machine is shared")
    ap.add_argument("--child", choices=sorted(CHILDREN), help=argparse.SUPPRESS)
    ap.add_argument("--dir", help=argparse.SUPPRESS)
    ap.add_argument("--limit", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    MIX = args.mix
    os.environ["BENCH_MIX"] = MIX  # the measuring children rebuild the same scenario
    if args.child:
        res = CHILDREN[args.child](Path(args.dir), args.limit, args.repeat)
        print(json.dumps(res))
        return 0

    n = args.frames or (50_000 if args.quick else 100_000 if args.profile else 20_000 if args.instructions
                        else 1_000_000)
    now = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    print(f"bench_pipeline {now}: {' '.join(sys.argv[1:]) or '(defaults)'}; {n:,} frames; {revision()}; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(prefix="bench-pipeline-") as tmp:
        folder = Path(tmp)
        meta = generate(n, folder)
        print(f"generated {meta['truth_frames']:,} frames in {meta['gen_s']} s", flush=True)
        if args.profile:
            print_profile(run_child("profile", folder), 30)
            return 0
        if args.instructions:
            r = per_frame_instructions(folder, meta["truth_frames"], meta["chunks"])
            print(f"instructions per frame (valgrind Ir, {MIX} mix): full decode -> JSONL {r['ours']:,.0f} "
                  f"({r['frames_ours']:,} frames); pymodbus best case {r['pymodbus']:,.0f} "
                  f"({r['frames_pymodbus']:,} frames); ours / pymodbus speed: {r['pymodbus'] / r['ours']:.2f}x")
            return 0
        res = {}
        for kind in ("split", "full", "verify", "pymodbus-stream", "pymodbus-split"):
            res[kind] = run_child(kind, folder, repeat=args.repeat)
            print(f"  {kind}: done", flush=True)
        res["stream_q"] = run_child("stream", folder, meta["quarter_chunks"])
        res["stream_n"] = run_child("stream", folder)
        print("  stream: done", flush=True)
        report(meta, res, sigrok_peer(folder, args.sigrok_capture), n)
    return 0


if __name__ == "__main__":
    sys.exit(main())
