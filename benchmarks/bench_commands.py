"""Every sniffer command on a 1,000,000-frame capture: peak RSS and frames/s, each in a fresh process.

    .venv/bin/python benchmarks/bench_commands.py [--frames N] [--quick] [--mix drive|stress]
                                                  [--only CMD] [--keep DIR] [--repeat K]

1. Generate (not timed) the captures a user would have, through the sniffer's own
   session: bench_pipeline's scenario (`--mix drive`, the default: the polls a PLC
   makes on a drive link, with errors; `--mix stress`: 125-register reads) at
   115200 8N1 through the FTDI read model, run by `Session(SimulatedSource, [mcap,
   bytecsv sinks])` for enough bus time to give at least N frames.  Written: the
   MCAP and the same bytes as a byte CSV; the pcap by `sniffer export --to pcap`;
   the N/4 capture (same seed, a quarter of the bus time: the first quarter of the
   same traffic) likewise; a second capture (seed + 1, same size) for `diff`; a copy
   of the MCAP cut in the middle for `repair`; the wire frames (truth.bin, in
   bench_pipeline's format) for the pymodbus peer.  `--keep DIR` keeps them there
   and reuses them on the next run with the same N, mix and seed.
2. Run each command in a fresh process (`--run`: this script calls
   `sniffer.cli.main(argv)`, stdout on /dev/null, and reports its own wall time,
   CPU time and peak RSS (VmHWM: see `peak_rss_mb`); the clock starts before `sniffer.cli` is imported, so
   imports are in the figure, interpreter start-up is not), once on the N/4 capture
   and once on the N capture.  The exit code must be the expected one and the
   outputs must be there and complete (rows / lines / packets counted after the
   run, not timed); a failed command is a row that says FAILED, not a missing row.
3. Peers, in the same run, each in a fresh process too: pymodbus' best case (frames
   pre-split, direction known: bench_pipeline's `child_pymodbus_split`) on the same
   wire frames; `tshark -r` of the same pcap with the mbrtu dissector (a summary
   line per packet to a file); pyarrow and Python's csv module writing the same
   number of frame and point rows, pre-built in memory, as our parquet and csv
   exports write (the writer alone: the floor of an export).

Targets printed next to the figures: peak RSS < 100 MB and >= 50,000 frames/s for
every command, and flat memory (the N-frame peak within 10 % of the N/4 one).
frames/s = frames in the input capture(s) / wall seconds of the whole command.
Nothing is asserted: tests never assert wall-clock times.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_pipeline as bp  # noqa: E402 - the scenario, truth format, machine and revision lines

TARGET_RSS_MB = 100.0  # peak RSS, MB (10^6 bytes)
TARGET_FPS = 50_000  # frames/s
FLAT_TOLERANCE = 0.10
BAUD = str(bp.LINE.baud)  # a byte CSV and a pcap do not say their line settings
GEN_VERSION = 1  # bump when the generated files change shape (the --keep cache)


# ------------------------------------------------------------------ the captures
def _tee_source(scenario, duration: float, seed: int, truth_path: Path | None):
    """SimulatedSource that also writes every wire frame but noise to truth.bin (bench_pipeline's format)."""
    from sniffer.simulator import KIND_CORRUPTED, KIND_NOISE, KIND_REQUEST, simulate, usb_chunks
    from sniffer.simulator.sources import SimulatedSource

    class TeeSource(SimulatedSource):
        def events(self):
            if truth_path is None:
                yield from super().events()
                return
            with open(truth_path, "wb") as out:
                def frames():
                    for wf in simulate(self.scenario, self.line, self.duration_s, self.seed):
                        if wf.kind != KIND_NOISE:
                            is_req = wf.role in (KIND_REQUEST, "broadcast")
                            out.write(bp._TRUTH.pack(0 if is_req else 1, wf.kind != KIND_CORRUPTED, len(wf.raw)))
                            out.write(wf.raw)
                        yield wf

                for ev in usb_chunks(frames(), seed=self.seed):
                    if self._stop:
                        return
                    yield ev

    return TeeSource(scenario, bp.LINE, duration, seed, "usb")


def _simulate_to(folder: Path, stem: str, duration: float, seed: int, truth: bool = False) -> dict:
    """STEM.mcap and STEM.csv of the bench scenario, written by one sniffer session."""
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.formats import FileSink

    src = _tee_source(bp.bench_scenario(), duration, seed, folder / "truth.bin" if truth else None)
    sinks = [FileSink("mcap", folder / f"{stem}.mcap"), FileSink("bytecsv", folder / f"{stem}.csv")]
    s = Session(CaptureSpec(), src, sinks, keep_partial=True).run()
    if s.error:
        raise SystemExit(f"bench: generating {stem}: {s.error}")
    return {"frames": s.frames_out, "bytes": s.bytes_in, "noise_bytes": s.noise_bytes}


def _frame_rate(scenario, seconds: float = 20.0) -> float:
    """Frames (noise excluded) per second of bus time, measured on a short run."""
    from sniffer.simulator import KIND_NOISE, simulate

    return sum(1 for f in simulate(scenario, bp.LINE, seconds, bp.SEED) if f.kind != KIND_NOISE) / seconds


def _sniffer(*argv: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("sniffer")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "sniffer"]
    return subprocess.run(cmd + list(argv), capture_output=True, text=True)


def generate(n: int, folder: Path, mix: str) -> dict:
    """The captures of the module doc, in `folder` (reused when meta.json says they are these)."""
    want = {"version": GEN_VERSION, "frames_asked": n, "mix": mix, "seed": bp.SEED}
    meta_path = folder / "meta.json"
    if meta_path.exists():
        meta = json.loads(meta_path.read_text())
        if {k: meta.get(k) for k in want} == want and all((folder / f).exists() for f in meta["files"]):
            meta["cached"] = True
            return meta
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    rate = _frame_rate(bp.bench_scenario())
    duration = n / rate * 1.02 + 1.0  # frames per bus second are steady: 2 % margin
    caps = {
        "full": _simulate_to(folder, "full", duration, bp.SEED, truth=True),
        "quarter": _simulate_to(folder, "quarter", duration / 4, bp.SEED),
        "other": _simulate_to(folder, "other", duration, bp.SEED + 1),
        "other_quarter": _simulate_to(folder, "other_quarter", duration / 4, bp.SEED + 1),
    }
    for stem in ("full", "quarter"):
        r = _sniffer("export", str(folder / f"{stem}.mcap"), "--to", "pcap", "--out", str(folder / f"{stem}.pcap"))
        if r.returncode != 0:
            raise SystemExit(f"bench: sniffer export --to pcap failed ({r.returncode}): {r.stderr.strip()}")
        data = (folder / f"{stem}.mcap").read_bytes()  # cut in the middle: what a killed capture leaves
        (folder / f"{stem}_cut.mcap").write_bytes(data[: len(data) // 2])
        caps[stem]["packets"] = count_pcap(folder / f"{stem}.pcap")
    stress = _frame_rate(_stress())
    meta = {
        **want, "scenario": bp.bench_scenario().name, "line": bp.LINE.label(), "rate_per_bus_s": round(rate, 1),
        "sim_duration_s": round(duration, 1), "captures": caps,
        "stress_rate_per_bus_s": round(stress, 1), "gen_s": round(time.perf_counter() - t0, 1),
        "generated_with": bp.revision(), "cached": False,
        "files": sorted(p.name for p in folder.iterdir() if p.is_file()),
    }
    meta_path.write_text(json.dumps(meta, indent=1))
    return meta


def _stress():
    from sniffer.simulator import get_scenario

    return get_scenario("stress")


# ------------------------------------------------------------- output checks
def count_pcap(path: Path) -> int:
    """Packets in a classic pcap or a pcapng file (walking the record headers)."""
    n = 0
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] == b"\x0a\x0d\x0d\x0a":
        pos = 0
        while pos + 12 <= len(data):
            btype, blen = struct.unpack_from("<II", data, pos)
            n += btype == 6
            pos += blen
        return n
    pos = 24
    while pos + 16 <= len(data):
        incl = struct.unpack_from("<I", data, pos + 8)[0]
        pos += 16 + incl
        n += 1
    return n


def count_lines(path: Path) -> int:
    n = 0
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            n += block.count(b"\n")
    return n


def count_parquet(path: Path) -> int:
    import pyarrow.parquet as pq

    return pq.ParquetFile(path).metadata.num_rows


def count_mcap_frames(path: Path) -> int:
    """/frames messages in a finished MCAP (its summary's statistics)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.id: c.topic for c in summary.channels.values()}
    return sum(n for cid, n in summary.statistics.channel_message_counts.items() if topics.get(cid) == "/frames")


# ------------------------------------------------------------- the commands
class Row:
    """One command: its argv for a capture size, what it must exit with, and what it must have written."""

    def __init__(self, name: str, what: str, argv, rc=(0,), outputs=(), inputs=("full",), check=None, needs=None):
        self.name, self.what, self.argv, self.rc = name, what, argv, rc
        self.outputs, self.inputs, self.check, self.needs = outputs, inputs, check, needs


def _rows(folder: Path, out: Path, meta: dict) -> list[Row]:
    def cap(size: str, ext: str = "mcap", other: bool = False) -> str:
        stem = ("other_" if other else "") + ("full" if size == "full" else "quarter")
        if other and size == "full":
            stem = "other"
        return str(folder / f"{stem}.{ext}")

    def o(name: str) -> str:
        return str(out / name)

    def frames_file(count, expect: str):
        """A check: the output holds as many frames (rows, lines, packets) as the command decoded."""
        def check(res: dict) -> str | None:
            decoded = res["decoded"]
            got = count(res)
            res["out_count"] = got
            want = decoded + (1 if expect == "+header" else 0)
            return None if got == want else f"output holds {got:,} {expect.lstrip('+')} rows, {want:,} expected"
        return check

    def export(fmt: str, fname: str, counter, expect="frames"):
        path = out / fname
        outputs = [fname] + ([fname.replace(f".{fmt}", f".points.{fmt}")] if fmt in ("csv", "parquet") else [])
        return Row(f"export {fmt}", f"export --to {fmt} (MCAP in, {fname} out)",
                   lambda s, fmt=fmt, fname=fname: ["export", cap(s), "--to", fmt, "--out", o(fname)],
                   outputs=outputs, check=frames_file(lambda _res: counter(path), expect))

    stress_s = meta["_n"] / meta["stress_rate_per_bus_s"]
    return [
        Row("replay", "replay FILE.mcap, text on stdout (/dev/null)", lambda s: ["replay", cap(s)]),
        Row("replay jsonl", "replay FILE.mcap --format jsonl (/dev/null)",
            lambda s: ["replay", cap(s), "--format", "jsonl"]),
        Row("replay csv", "replay FILE.csv (byte CSV of the same capture) --baud, text",
            lambda s: ["replay", cap(s, "csv"), "--baud", BAUD]),
        Row("replay pcap", "replay FILE.pcap (our pcap export of it) --baud, text",
            lambda s: ["replay", cap(s, "pcap"), "--baud", BAUD]),
        export("csv", "x.csv", lambda p: count_lines(p), "+header"),
        export("parquet", "x.parquet", count_parquet),
        export("pcap", "x.pcap", count_pcap),
        export("pcapng", "x.pcapng", count_pcap),
        export("mcap", "x.mcap", count_mcap_frames),
        export("jsonl", "x.jsonl", count_lines),
        Row("check --update-golden", "check FILE.mcap --golden G --update-golden (writes G; no G before)",
            lambda s: ["check", cap(s), "--golden", o(f"golden-{s}.txt"), "--update-golden"],
            outputs=["golden-{s}.txt"],
            check=frames_file(lambda res: count_lines(out / f"golden-{res['size']}.txt"), "+header")),
        Row("check", "check FILE.mcap --golden G (the golden just written: exit 0, same)",
            lambda s: ["check", cap(s), "--golden", o(f"golden-{s}.txt")], needs="check --update-golden"),
        Row("diff", "diff FILE.mcap OTHER.mcap (seed + 1, same size): both decoded; exit 1, they differ",
            lambda s: ["diff", cap(s), cap(s, other=True)], rc=(1,), inputs=("full", "other")),
        Row("report", "report FILE.mcap --out report.html (the page holds the frame count)",
            lambda s: ["report", cap(s), "--out", o(f"report-{s}.html")], outputs=["report-{s}.html"],
            check=_report_check(out)),
        Row("diagnose", "diagnose FILE.mcap (findings, text on stdout)", lambda s: ["diagnose", cap(s)]),
        Row("repair", "repair CUT.mcap (the MCAP cut at half its bytes) -o OUT",
            lambda s: ["repair", str(folder / f"{'full' if s == 'full' else 'quarter'}_cut.mcap"),
                       "-o", o("repaired.mcap")],
            outputs=["repaired.mcap"], inputs=()),
        Row("simulate", f"simulate --scenario stress --duration S --out OUT.mcap (S = {stress_s:,.0f} s at N)",
            lambda s: ["simulate", "--scenario", "stress", "--seed", str(bp.SEED), "--duration",
                       f"{stress_s * (1.0 if s == 'full' else 0.25):.1f}", "--out", o("sim.mcap")],
            outputs=["sim.mcap"], inputs=()),
    ]


def _report_check(out: Path):
    """A check: the report is a complete page whose data block counts the frames the command decoded."""
    def check(res: dict) -> str | None:
        text = (out / f"report-{res['size']}.html").read_text(encoding="utf-8")
        start = text.find('id="report-data">')
        blob = text[start + len('id="report-data">'): text.find("</script>", start)]
        got = json.loads(blob.replace("<\\/", "</"))["totals"]["frames"] if start >= 0 else None
        res["out_count"] = got
        ok = text.rstrip().endswith("</html>") and got == res["decoded"]
        return None if ok else f"report holds {got} frames, {res['decoded']:,} decoded"
    return check


# ------------------------------------------------------------- the child
def peak_rss_mb() -> float:
    """This process's peak RSS in MB: VmHWM, the high-water mark of its own address space.

    Not ru_maxrss: on Linux that keeps the largest RSS the process had *before* exec
    too, and a child forked from this benchmark starts as a copy of it, so its
    ru_maxrss is never below the benchmark's own RSS at the moment it was started.
    """
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024 / 1e6
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6


def child_run(result: Path, argv: list[str], mem_limit_mb: int) -> int:
    """Run `sniffer argv` in this process and write what it cost to `result` (JSON)."""
    t0 = time.perf_counter()
    if mem_limit_mb:
        lim = mem_limit_mb * 1024 * 1024
        resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
    sessions: list[dict] = []
    from sniffer.capture import session as _session

    end = _session.Session._end

    def counting_end(self, completed):  # one call per session: what it decoded
        first = not self.ended
        end(self, completed)
        if first:
            sessions.append({"frames": self.frames_out, "bytes": self.bytes_in, "error": self.error})

    _session.Session._end = counting_end
    from sniffer.cli import main

    t_import = time.perf_counter() - t0
    err = None
    prof = None
    if os.environ.get("BENCH_PROFILE"):
        import cProfile

        prof = cProfile.Profile()
    try:
        rc = main(argv) if prof is None else prof.runcall(main, argv)
    except SystemExit as e:  # argparse's --version and --help
        rc = e.code if isinstance(e.code, int) else 0
    except MemoryError:
        rc, err = -1, "MemoryError (over --mem-limit-mb)"
    except BaseException as e:  # noqa: BLE001 - a crash is a reported failure
        rc, err = -1, f"{type(e).__name__}: {e}"
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_SELF)
    sys.stdout.flush()
    result.write_text(json.dumps({
        "rc": rc, "error": err, "wall": wall, "import_s": t_import, "cpu": ru.ru_utime + ru.ru_stime,
        "rss_mb": peak_rss_mb(), "ru_maxrss_mb": ru.ru_maxrss * 1024 / 1e6, "sessions": sessions,
        "profile": _profile_rows(prof) if prof is not None else None,
    }))
    return 0


def _profile_rows(prof) -> dict:
    """The top functions of a cProfile run, by cumulative and by own time (percent of the command)."""
    import pstats

    st = pstats.Stats(prof)
    total = max(v[3] for v in st.stats.values()) or 1.0
    root = str(HERE.parent) + os.sep

    def name(file: str, line: int, fn: str) -> str:
        short = file[len(root):] if file.startswith(root) else Path(file).name
        return f"{short}:{line}({fn})"

    rows = [(100 * ct / total, 100 * tt / total, nc, name(*key)) for key, (_cc, nc, tt, ct, _c) in st.stats.items()]
    return {"total_s": total, "cum": sorted(rows, reverse=True)[:30],
            "own": sorted(rows, key=lambda r: -r[1])[:15]}


def print_profile(row_name: str, res: dict) -> None:
    p = res.get("profile")
    if not p:
        print(f"{row_name}: no profile ({'; '.join(res['problems']) or 'none recorded'})")
        return
    print(f"\ncProfile of `sniffer {' '.join(res['argv'])}` ({res['frames']:,} frames, {p['total_s']:.1f} s "
          f"under the profiler)")
    for title, key in (("by cumulative time", "cum"), ("by own time", "own")):
        print(f"  {title}:\n  {'cum %':>6} {'own %':>6} {'calls':>11}  function")
        for cum, own, calls, fn in p[key]:
            print(f"  {cum:6.1f} {own:6.1f} {calls:11,}  {fn}")


def run_measured(argv: list[str], mem_limit_mb: int, profile: bool = False) -> dict:
    with tempfile.NamedTemporaryFile(prefix="bench-cmd-", suffix=".json", delete=False) as tf:
        res_path = Path(tf.name)
    try:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--run", str(res_path),
               "--mem-limit-mb", str(mem_limit_mb), "--", *argv]
        load = os.getloadavg()[0]
        env = {**os.environ, "BENCH_PROFILE": "1"} if profile else None
        p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        try:
            res = json.loads(res_path.read_text())
        except (OSError, ValueError):
            res = {"rc": None, "error": f"no result (child exit {p.returncode})", "wall": 0, "cpu": 0, "rss_mb": 0,
                   "sessions": []}
    finally:
        res_path.unlink(missing_ok=True)
    res["stderr"] = p.stderr
    res["load"] = load
    return res


# ------------------------------------------------------------- peers
def child_peer(kind: str, folder: Path, n_rows: int) -> dict:
    t0 = time.perf_counter()
    if kind == "pymodbus":
        r = bp.child_pymodbus_split(folder, None, 1)  # loads truth.bin, then times the decode loop alone
        r["wall"] = time.perf_counter() - t0
    else:
        r = _writer_peer(kind, folder, n_rows)
    ru = resource.getrusage(resource.RUSAGE_SELF)
    r["rss_mb"] = peak_rss_mb()
    r["cpu"] = ru.ru_utime + ru.ru_stime
    return r


def _writer_peer(kind: str, folder: Path, n_frames: int) -> dict:
    """pyarrow / csv writing n_frames frame rows (and their point rows), pre-built, as our export does."""
    import csv as _csv

    from sniffer.capture.session import decode_capture
    from sniffer.formats.rows import frame_row, point_rows

    sample = 32_768  # one batch of our parquet sink; the sample repeats to n_frames (the rows are the same objects)
    session = decode_capture(folder / "full.mcap")
    t0n, anchor = session.info.t0_ns, session.info.wall_anchor_ns
    fr: list[tuple] = []
    pr: list[list[tuple]] = []
    for f in session:
        fr.append(frame_row(f, t0n, anchor))
        pr.append(point_rows(f, t0n))
        if len(fr) >= sample:
            break
    session.close()
    out = folder / "peer-out"
    out.mkdir(exist_ok=True)
    n_points = 0
    t0 = time.perf_counter()
    if kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        from sniffer.formats.parquet import BATCH, schemas

        fs, ps = schemas()
        wf, wp = pq.ParquetWriter(out / "peer.parquet", fs), pq.ParquetWriter(out / "peer.points.parquet", ps)

        def write(w, schema, rows):
            w.write_table(pa.Table.from_arrays([pa.array(c, type=fld.type) for c, fld in zip(zip(*rows), schema)],
                                               schema=schema))

        rf: list[tuple] = []
        rp: list[tuple] = []
        for i in range(n_frames):
            rf.append(fr[i % sample])
            pts = pr[i % sample]
            if pts:
                rp.extend(pts)
                n_points += len(pts)
            if len(rf) >= BATCH:
                write(wf, fs, rf)
                rf = []
            if len(rp) >= BATCH:
                write(wp, ps, rp)
                rp = []
        if rf:
            write(wf, fs, rf)
        if rp:
            write(wp, ps, rp)
        wf.close()
        wp.close()
    else:
        from sniffer.formats.rows import FRAME_COLUMNS, POINT_COLUMNS

        with open(out / "peer.csv", "w", newline="") as ff, open(out / "peer.points.csv", "w", newline="") as fp:
            w1, w2 = _csv.writer(ff), _csv.writer(fp)
            w1.writerow(FRAME_COLUMNS)
            w2.writerow(POINT_COLUMNS)
            for start in range(0, n_frames, 4096):
                idx = range(start, min(start + 4096, n_frames))
                w1.writerows(fr[i % sample] for i in idx)
                pts = [p for i in idx for p in pr[i % sample]]
                n_points += len(pts)
                w2.writerows(pts)
    dt = time.perf_counter() - t0
    shutil.rmtree(out, ignore_errors=True)
    return {"frames": n_frames, "points": n_points, "seconds": dt}


def run_peer(kind: str, folder: Path, n_rows: int = 0) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--peer", kind, "--dir", str(folder), "--rows", str(n_rows)]
    load = os.getloadavg()[0]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1], "load": load}
    r = json.loads(p.stdout.strip().splitlines()[-1])
    r["load"] = load
    return r


def tshark_peer(pcap: Path, out_dir: Path) -> dict:
    """tshark -r PCAP with the mbrtu dissector on DLT 147, one summary line per packet to a file."""
    from sniffer.formats.pcap.writer import TSHARK_ARGS

    exe = shutil.which("tshark")
    if not exe:
        return {"error": "tshark not installed (apt-get install tshark)"}
    txt, usage = out_dir / "tshark.txt", out_dir / "tshark.time"
    # through /usr/bin/time, a small process: tshark's ru_maxrss then is its own (see peak_rss_mb)
    timer = ["/usr/bin/time", "-o", str(usage), "-f", "%M %U %S"] if os.path.exists("/usr/bin/time") else []
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    with open(txt, "wb") as fh:
        p = subprocess.run([*timer, exe, "-n", "-r", str(pcap), *TSHARK_ARGS], stdout=fh, stderr=subprocess.PIPE)
    dt = time.perf_counter() - t0
    err, rc = p.stderr.decode(errors="replace"), p.returncode
    rss = cpu = 0.0
    if timer:
        try:
            kib, user, system = usage.read_text().split()[-3:]
            rss, cpu = int(kib) * 1024 / 1e6, float(user) + float(system)
        except (OSError, ValueError):
            pass
        usage.unlink(missing_ok=True)
    lines = modbus = 0
    with open(txt, "rb") as fh:
        for line in fh:
            lines += 1
            modbus += b"Modbus" in line
    txt.unlink()
    if rc != 0:
        return {"error": f"tshark exit {rc}: {err.strip()[:200]}", "load": load}
    return {"seconds": dt, "cpu": cpu, "rss_mb": rss, "packets": lines, "modbus": modbus, "load": load}


# ------------------------------------------------------------- running and reporting
def measure(row: Row, size: str, folder: Path, out: Path, meta: dict, mem_limit_mb: int,
            profile: bool = False) -> dict:
    caps = meta["captures"]
    argv = row.argv(size)
    for name in row.outputs:  # a golden left by an earlier run would be compared, not just written
        (out / name.format(s=size)).unlink(missing_ok=True)
    res = run_measured(argv, mem_limit_mb, profile)
    res["argv"] = argv
    res["size"] = size
    res["decoded"] = sum(s["frames"] for s in res["sessions"])
    if row.name == "repair" or row.name == "simulate":
        path = out / row.outputs[0]
        try:
            res["frames"] = count_mcap_frames(path)
        except Exception:  # noqa: BLE001 - a missing or unreadable output is reported below
            res["frames"] = 0
        if row.name == "simulate":
            res["decoded"] = res["frames"]
    else:
        key = {"full": {"full": "full", "other": "other"}, "quarter": {"full": "quarter", "other": "other_quarter"}}
        res["frames"] = sum(caps[key[size][i]]["frames"] for i in row.inputs)
    problems = []
    if res.get("error"):
        problems.append(res["error"])
    if res["rc"] not in row.rc:
        last = (res["stderr"].strip().splitlines() or [""])[-1]
        problems.append(f"exit {res['rc']} (expected {'/'.join(map(str, row.rc))}){': ' + last if last else ''}")
    for name in row.outputs:
        p = out / name.format(s=size)
        if not p.exists() or p.stat().st_size == 0:
            problems.append(f"{p.name} missing or empty")
    if not problems and row.check is not None:
        why = row.check(res)
        if why:
            problems.append(why)
    if not problems and row.inputs and res["decoded"] != res["frames"]:
        res["note"] = f"decoded {res['decoded']:,} of {res['frames']:,} frames"
    res["problems"] = problems
    return res


def _mb(x: float) -> str:
    return f"{x:,.1f}"


def _fps(frames: int, seconds: float) -> float:
    return frames / seconds if seconds > 0 else 0.0


def table(rows: list[list[str]]) -> list[str]:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for i, r in enumerate(rows):
        out.append("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip())
        if i == 0:
            out.append("  ".join("-" * w for w in widths))
    return out


def report(results: list[tuple[Row, dict, dict]], peers: dict, startup: dict) -> None:
    head = ["command", "N/4: peak MB", "N: peak MB", "flat", "N: frames/s", "wall s", "frames/CPU s", "CPU s",
            "load", "RSS < 100 MB", ">= 50k frames/s", "notes"]
    rows = [head]
    missed = []
    for row, q, n in results:
        failed = [f"{r['size']}: {'; '.join(r['problems'])}" for r in (q, n) if r and r["problems"]]
        if failed:
            rows.append([row.name, _mb(q["rss_mb"]) if q else "-", _mb(n["rss_mb"]) if n else "-", "-", "FAILED",
                         f"{n['wall']:.2f}" if n else "-", "-", "-", f"{n['load']:.1f}" if n else "-", "-", "-",
                         " | ".join(failed)[:300]])
            missed.append(f"{row.name}: FAILED ({' | '.join(failed)[:300]})")
            continue
        growth = (n["rss_mb"] - q["rss_mb"]) / q["rss_mb"] if q and q["rss_mb"] else 0.0
        flat = f"{'flat' if growth <= FLAT_TOLERANCE else 'GROWS'} ({100 * growth:+.0f} %)"
        fps = _fps(n["frames"], n["wall"])
        cps = _fps(n["frames"], n["cpu"])
        ok_rss = n["rss_mb"] < TARGET_RSS_MB
        ok_fps = fps >= TARGET_FPS
        speed = "ok" if ok_fps else ("NOT MET (CPU: ok)" if cps >= TARGET_FPS else "NOT MET")
        notes = [x for x in (n.get("note"), f"{n['frames']:,} frames",
                             f"N/4: {_fps(q['frames'], q['wall']) / 1000:,.1f}k frames/s") if x]
        rows.append([row.name, _mb(q["rss_mb"]), _mb(n["rss_mb"]), flat, f"{fps / 1000:,.1f}k",
                     f"{n['wall']:.2f}", f"{cps / 1000:,.1f}k", f"{n['cpu']:.2f}", f"{n['load']:.1f}",
                     "ok" if ok_rss else "NOT MET", speed, "; ".join(notes)])
        what = [w for w, ok in (("RSS", ok_rss), ("frames/s", ok_fps), ("flat", growth <= FLAT_TOLERANCE)) if not ok]
        if what:
            missed.append(f"{row.name}: {', '.join(what)} not met ({_mb(n['rss_mb'])} MB peak, "
                          f"{fps / 1000:,.1f}k frames/s wall, {cps / 1000:,.1f}k per CPU second, "
                          f"N/4 -> N {100 * growth:+.0f} %)")
    print()
    for line in table(rows):
        print(line)
    print(f"\nstart-up alone (`sniffer --version` in a fresh process): {startup['wall']:.2f} s, "
          f"{_mb(startup['rss_mb'])} MB peak RSS")
    print("rows:")
    for row, _q, _n in results:
        print(f"  {row.name:22} {row.what}")

    prow = [["peer", "what it measures", "peak MB", "frames/s", "seconds", "vs ours"]]
    ours = {row.name: n for row, _q, n in results if n and not n["problems"]}

    def vs(name: str, fps: float) -> str:
        r = ours.get(name)
        return f"{name}: {_fps(r['frames'], r['wall']) / fps:.2f}x of it" if r and fps else "-"

    pm = peers.get("pymodbus")
    if pm:
        if "error" in pm:
            prow.append(["pymodbus best case", "-", "-", pm["error"][:120], "-", "-"])
        else:
            fps = _fps(pm["frames"], pm["seconds"])
            prow.append(["pymodbus best case",
                         f"FramerRTU.handleFrame on the {pm['frames']:,} wire frames, pre-split, direction known "
                         f"({pm['decoded']:,} decoded, held in a list); no pairing, no output; the loop is timed "
                         f"(the whole process: {pm['wall']:.1f} s)",
                         _mb(pm["rss_mb"]), f"{fps / 1000:,.1f}k", f"{pm['seconds']:.2f}",
                         vs("replay jsonl", fps)])
    ts = peers.get("tshark")
    if ts:
        if "error" in ts:
            prow.append(["tshark -r PCAP", "-", "-", ts["error"][:120], "-", "-"])
        else:
            fps = _fps(ts["packets"], ts["seconds"])
            tq = peers.get("tshark_q") or {}
            quarter = f"; N/4: {_mb(tq['rss_mb'])} MB peak" if "rss_mb" in tq else ""
            prow.append(["tshark -r PCAP", f"tshark {_tshark_version()} -n -r full.pcap, mbrtu on DLT 147, a summary "
                         f"line per packet to a file ({ts['packets']:,} lines, {ts['modbus']:,} Modbus{quarter})",
                         _mb(ts["rss_mb"]), f"{fps / 1000:,.1f}k", f"{ts['seconds']:.2f}", vs("replay pcap", fps)])
    for kind, ours_name, what in (
        ("parquet", "export parquet", "pyarrow ParquetWriter, our schemas, a row group every 32,768 rows, the rows "
                                      "pre-built: the first 32,768 frames' rows, repeated (held all along: in the MB)"),
        ("csv", "export csv", "csv.writer.writerows, the rows pre-built: the first 32,768 frames' rows, repeated"),
    ):
        pr = peers.get(kind)
        if not pr:
            continue
        if "error" in pr:
            prow.append([f"{kind} writer alone", "-", "-", pr["error"][:120], "-", "-"])
            continue
        fps = _fps(pr["frames"], pr["seconds"])
        prow.append([f"{kind} writer alone", f"{what} ({pr['frames']:,} frames, {pr['points']:,} points)",
                     _mb(pr["rss_mb"]), f"{fps / 1000:,.1f}k", f"{pr['seconds']:.2f}", vs(ours_name, fps)])
    if len(prow) > 1:
        print("\npeers, measured in the same run (each in a fresh process):")
        for line in table(prow):
            print(line)
    print()
    if missed:
        print("targets missed:")
        for m in missed:
            print(f"  {m}")
    else:
        print("every command met every target")


def _tshark_version() -> str:
    try:
        r = subprocess.run(["tshark", "--version"], capture_output=True, text=True)
        return r.stdout.split()[2]
    except (OSError, IndexError):
        return "?"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=None, help="frames in the capture (default 1,000,000)")
    ap.add_argument("--quick", action="store_true", help="50,000 frames: a check that everything runs")
    ap.add_argument("--mix", choices=bp.MIXES, default="drive",
                    help="drive: typical PLC-drive polls (default); stress: 125-register reads")
    ap.add_argument("--only", action="append", metavar="CMD",
                    help="run only this row (e.g. 'export parquet', 'replay'; repeatable; 'peers' for the peers)")
    ap.add_argument("--keep", metavar="DIR", help="generate the captures in DIR and reuse them next time")
    ap.add_argument("--no-peers", action="store_true", help="skip the peers")
    ap.add_argument("--profile", action="store_true",
                    help="instead: run the --only rows on the N/4 capture under cProfile and print the top functions")
    ap.add_argument("--mem-limit-mb", type=int, default=8000,
                    help="address-space limit of each measured process (MB; 0 = none): a runaway is a failed row, "
                         "not a machine out of memory (default 8000)")
    ap.add_argument("--run", help=argparse.SUPPRESS)
    ap.add_argument("--peer", help=argparse.SUPPRESS)
    ap.add_argument("--dir", help=argparse.SUPPRESS)
    ap.add_argument("--rows", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    bp.MIX = args.mix
    os.environ["BENCH_MIX"] = args.mix
    if args.run:
        rest = args.rest[1:] if args.rest[:1] == ["--"] else args.rest
        return child_run(Path(args.run), rest, args.mem_limit_mb)
    if args.peer:
        print(json.dumps(child_peer(args.peer, Path(args.dir), args.rows)))
        return 0

    n = args.frames or (50_000 if args.quick else 1_000_000)
    now = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    print(f"bench_commands {now}: {' '.join(sys.argv[1:]) or '(defaults)'}; {n:,} frames; {bp.revision()}; "
          f"load average at start {', '.join(f'{x:.2f}' for x in os.getloadavg())}", flush=True)
    tmp = None
    if args.keep:
        folder = Path(args.keep)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="bench-commands-")
        folder = Path(tmp.name)
    try:
        meta = generate(n, folder, args.mix)
        meta["_n"] = n
        c = meta["captures"]
        how = "reused from " + str(folder) + f" (generated with {meta['generated_with']})" if meta["cached"] else \
            f"generated in {meta['gen_s']} s (not timed)"
        print(f"captures {how}: scenario {meta['scenario']} at {meta['line']}, seed {meta['seed']}, "
              f"{meta['rate_per_bus_s']:,} frames per bus second, {meta['sim_duration_s']:,} s of bus time")
        for key in ("full", "quarter", "other", "other_quarter"):
            sizes = ", ".join(f"{ext} {(folder / f'{key}.{ext}').stat().st_size / 1e6:,.1f} MB"
                              for ext in ("mcap", "csv", "pcap") if (folder / f"{key}.{ext}").exists())
            print(f"  {key}: {c[key]['frames']:,} frames, {c[key]['bytes'] / 1e6:,.2f} MB of wire; {sizes}")
        out = folder / "out"
        out.mkdir(exist_ok=True)
        rows = _rows(folder, out, meta)
        names = {r.name for r in rows}
        only = set(args.only or ())
        unknown = only - names - {"peers"}
        if unknown:
            raise SystemExit(f"bench: unknown --only {', '.join(sorted(unknown))} (one of: {', '.join(sorted(names))}, "
                             "peers)")
        if args.profile:
            for row in rows:
                if only and row.name not in only:
                    continue
                if row.needs:
                    run_measured(next(r for r in rows if r.name == row.needs).argv("quarter"), args.mem_limit_mb)
                print_profile(row.name, measure(row, "quarter", folder, out, meta, args.mem_limit_mb, profile=True))
            return 0
        startup = run_measured(["--version"], args.mem_limit_mb)
        results = []
        for row in rows:
            if only and row.name not in only:
                continue
            if row.needs and (not only or row.needs not in only):  # its input, made untimed
                need = next(r for r in rows if r.name == row.needs)
                for size in ("quarter", "full"):
                    run_measured(need.argv(size), args.mem_limit_mb)
            q = measure(row, "quarter", folder, out, meta, args.mem_limit_mb)
            n_res = measure(row, "full", folder, out, meta, args.mem_limit_mb)
            results.append((row, q, n_res))
            state = "FAILED" if q["problems"] or n_res["problems"] else "done"
            print(f"  {row.name}: {state} ({n_res['wall']:.1f} s, {_mb(n_res['rss_mb'])} MB)", flush=True)
            for name in os.listdir(out):  # the outputs of a 1M-frame export take room: one row at a time
                if not name.startswith("golden-"):
                    (out / name).unlink()
        peers: dict = {}
        if not args.no_peers and (not only or "peers" in only):
            peers["pymodbus"] = run_peer("pymodbus", folder)
            peers["tshark_q"] = tshark_peer(folder / "quarter.pcap", out)
            peers["tshark"] = tshark_peer(folder / "full.pcap", out)
            peers["parquet"] = run_peer("parquet", folder, c["full"]["frames"])
            peers["csv"] = run_peer("csv", folder, c["full"]["frames"])
            print("  peers: done", flush=True)
        report(results, peers, startup)
        print("frames/s = frames in the input capture(s) / wall seconds of the whole command in a fresh process "
              "(imports included); the machine is shared: wall times move 20-30 % between runs (CPU s moves less)")
        print(f"machine: {bp.machine()}")
    finally:
        if tmp is not None:
            tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
