"""--jobs N (sniffer.parallel): every output byte for byte what one process writes.

The captures are cut into parts of a few dozen events (`small_parts`), so every
capture has many cuts, and each is decoded with --jobs 1 and --jobs 2 through the
CLI in this process; stdout, stderr, the exit code and every file written must be
equal.  The captures hold what crosses a cut: CRC errors, exceptions, timeouts and
noise (the `errors` scenario); units being identified (tds-v8, unmapped); a
register that scales others changing mid-capture and a broadcast answered just
after a cut (a synthetic TDS-V8 line); two links on one timeline; a rotated
capture's folder with a segment missing (a gap carrying the next segment's
decoder state); a capture cut short (damage); a line that is never quiet (no
quiet point to cut at: the rest decoded in order).
"""

from __future__ import annotations

import os
import re
import shutil

import pytest
from helpers import bursts, fr

from sniffer.cli import main
from sniffer.events import CaptureInfo, Chunk
from sniffer.line import LineSettings

LINE = LineSettings(19200, "E", 1)


@pytest.fixture
def small_parts(monkeypatch):
    """Parts of 40 events (a warm-up of 12, 64 looked at past the end): a cut every few transactions."""
    import sniffer.parallel.engine as engine

    monkeypatch.setattr(engine, "PART_EVENTS", 40)
    monkeypatch.setattr(engine, "WARM_EVENTS", 12)
    monkeypatch.setattr(engine, "OVER_EVENTS", 64)


def _cli(capfd, *args) -> tuple[int, bytes, str]:
    capfd.readouterr()
    rc = main([str(a) for a in args])
    out, err = capfd.readouterr()
    return rc, out.encode(), err


def _write_mcap(path, info: CaptureInfo, events) -> str:
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.formats import FileSink

    Session(CaptureSpec(), EventSource(info, events), [FileSink("mcap", str(path), timed_flush=False)]).run()
    return str(path)


def _tds_line() -> list[Chunk]:
    """Unit 1 a TDS-V8 (given): its output frequency polled, scaled through Cn-02 (0301H), which a write
    changes mid-capture; a broadcast write a unit answers (a bug the pairer flags), unanswered requests,
    CRC errors and noise, all over the capture."""
    read_cn02 = [fr("010303010001"), fr("0103020258")]  # Cn-02 = 600 (60.0 Hz)
    poll = [fr("010300250001"), fr("0103023A98")]  # output frequency: 15000 = 50 % of Cn-02
    frames: list[str] = [*read_cn02]
    for i in range(240):
        frames += poll
        if i == 120:
            frames += [fr("0106030101F4"), fr("0106030101F4")]  # Cn-02 written: 500 (50.0 Hz)
        if i % 37 == 5:
            frames += [fr("000600010BB8"), fr("010600010BB8")]  # a broadcast write, answered by unit 1
        if i % 29 == 7:
            frames += [fr("020300250001")]  # unit 2 never answers
        if i % 31 == 9:
            bad = bytearray(bytes.fromhex(fr("0103023A98")))
            bad[-1] ^= 0xFF
            frames += [poll[0], bad.hex()]
        if i % 43 == 11:
            frames += ["ffff00"]
    return bursts(frames, LINE, gap_chars=40)


def _dead_line() -> list[Chunk]:
    """A few answered polls, then a master polling a unit that never answers: never quiet again."""
    frames = [fr("010300250001"), fr("0103023A98")] * 20 + [fr("050300000002")] * 300
    return bursts(frames, LINE, gap_chars=200)


def _two_links() -> list[Chunk]:
    from sniffer.simulator import get_scenario, simulate, wire_chunks

    out = []
    for link, name, seed in (("a", "errors", 3), ("b", "tds-v8", 4)):
        sc = get_scenario(name)
        for c in wire_chunks(simulate(sc, sc.line, 20, seed)):
            out.append(Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link))
    return sorted(out, key=lambda c: c.t_ns)


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    """name -> the capture's path (a file or a rotated capture's folder)."""
    from sniffer.simulator import get_scenario

    d = tmp_path_factory.mktemp("parallel")
    out = {}
    assert main(["simulate", "--out", str(d / "errors.mcap"), "--scenario", "errors", "--duration", "40",
                 "--seed", "5"]) == 0
    out["errors"] = str(d / "errors.mcap")
    assert main(["simulate", "--out", str(d / "tds.mcap"), "--scenario", "tds-v8", "--duration", "30"]) == 0
    out["identified"] = str(d / "tds.mcap")
    info = CaptureInfo(baud=LINE.baud, parity=LINE.parity, stopbits=LINE.stopbits, devices={1: "tds-v8"})
    out["scaling"] = _write_mcap(d / "scaling.mcap", info, _tds_line())
    out["dead"] = _write_mcap(d / "dead.mcap", CaptureInfo(baud=LINE.baud, parity="E", stopbits=1), _dead_line())
    a, b = get_scenario("errors").line, get_scenario("tds-v8").line
    links = CaptureInfo(baud=a.baud, parity=a.parity, stopbits=a.stopbits, links=[
        {"name": "a", "baud": a.baud, "parity": a.parity, "stopbits": a.stopbits},
        {"name": "b", "baud": b.baud, "parity": b.parity, "stopbits": b.stopbits}])
    out["links"] = _write_mcap(d / "links.mcap", links, _two_links())
    folder = d / "rotated"
    assert main(["replay", out["errors"], "--quiet", "--jobs", "1", "--out", str(folder), "--rotate", "8s"]) == 0
    segments = sorted(p for p in os.listdir(folder) if p.endswith(".mcap"))
    assert len(segments) >= 4
    os.remove(folder / segments[2])  # a hole: the gap carries the next segment's decoder state
    out["rotated"] = str(folder)
    cut = d / "cut.mcap"
    data = open(out["errors"], "rb").read()
    cut.write_bytes(data[: len(data) * 3 // 5])  # killed mid-capture: damage at its end
    out["cut"] = str(cut)
    out["damaged"] = _damaged(out["errors"], d / "damaged.mcap")
    return out


def _damaged(path, out) -> str:
    """A finished capture with a byte of a chunk in its middle flipped: the chunk fails its CRC."""
    from sniffer.formats.mcap.ranges import raw_index

    index = raw_index(path)
    _first, _n, offset, length, _at = index.chunks[len(index.chunks) // 2]
    data = bytearray(open(path, "rb").read())
    data[offset + length - 20] ^= 0x55
    out.write_bytes(data)
    return str(out)


ALL = ["errors", "identified", "scaling", "dead", "links", "rotated", "cut", "damaged"]


def _same(capfd, args1: list, args2: list, files=()) -> None:
    one = _cli(capfd, *args1, "--jobs", "1")
    saved = {f: open(f, "rb").read() for f in files if os.path.exists(f)}
    two = _cli(capfd, *args2, "--jobs", "2")
    assert one[0] == two[0], (one[2], two[2])
    assert one[1].replace(b"one.", b"two.") == two[1]
    assert one[2].replace("one.", "two.") == two[2]
    for f in files:
        g = f.replace("one.", "two.")
        assert os.path.exists(f) == os.path.exists(g), f
        if f in saved:
            assert saved[f] == open(g, "rb").read(), f


@pytest.mark.parametrize("name", ALL)
@pytest.mark.parametrize("fmt", ["text", "jsonl"])
def test_replay_prints_what_one_process_prints(capfd, small_parts, captures, name, fmt):
    _same(capfd, ["replay", captures[name], "--format", fmt], ["replay", captures[name], "--format", fmt])


@pytest.mark.parametrize("name", ["errors", "scaling", "links", "rotated"])
@pytest.mark.parametrize("fmt", ["csv", "parquet", "pcap", "pcapng", "mcap", "jsonl"])
def test_export_writes_what_one_process_writes(capfd, tmp_path, small_parts, captures, name, fmt):
    ext = fmt
    one, two = str(tmp_path / f"one.{ext}"), str(tmp_path / f"two.{ext}")
    files = [one] + ([str(tmp_path / f"one.points.{ext}")] if fmt in ("csv", "parquet") else [])
    _same(capfd, ["export", captures[name], "--to", fmt, "--out", one],
          ["export", captures[name], "--to", fmt, "--out", two], files)


@pytest.mark.parametrize("name", ["identified", "scaling", "links", "cut"])
def test_check_and_its_golden_are_what_one_process_gives(capfd, tmp_path, small_parts, captures, name):
    one, two = str(tmp_path / "one.txt"), str(tmp_path / "two.txt")
    _same(capfd, ["check", captures[name], "--golden", one, "--update-golden"],
          ["check", captures[name], "--golden", two, "--update-golden"], [one])
    if not os.path.exists(one):
        return  # a damaged capture writes no golden
    lines = open(one).read().splitlines()
    lines[len(lines) // 2] = lines[len(lines) // 2].replace("crc=ok", "crc=BAD")
    open(two, "w").write("\n".join(lines) + "\n")
    shutil.copy(two, one)
    _same(capfd, ["check", captures[name], "--golden", one], ["check", captures[name], "--golden", two])


@pytest.mark.parametrize("name", ["errors", "identified", "links", "rotated", "cut"])
@pytest.mark.parametrize("fmt", ["text", "json"])
def test_diagnose_finds_what_one_process_finds(capfd, small_parts, captures, name, fmt):
    _same(capfd, ["diagnose", captures[name], "--format", fmt], ["diagnose", captures[name], "--format", fmt])


@pytest.mark.parametrize("name", ["errors", "identified"])
def test_check_with_findings_is_what_one_process_gives(capfd, tmp_path, small_parts, captures, name):
    one, two = str(tmp_path / "one.txt"), str(tmp_path / "two.txt")
    _same(capfd, ["check", captures[name], "--golden", one, "--findings", "--update-golden"],
          ["check", captures[name], "--golden", two, "--findings", "--update-golden"], [one])
    assert any(line.startswith("finding ") for line in open(one)), \
        "the golden holds findings"
    _same(capfd, ["check", captures[name], "--golden", one], ["check", captures[name], "--golden", two])


@pytest.mark.parametrize("names", [["errors", "links"], ["rotated"], ["cut", "scaling"]])
def test_report_is_what_one_process_writes(capfd, tmp_path, small_parts, captures, names):
    one, two = tmp_path / "one.html", tmp_path / "two.html"
    paths = [captures[n] for n in names]
    _same(capfd, ["report", *paths, "--out", one], ["report", *paths, "--out", two])

    def page(p):
        return re.sub(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", "T", p.read_text())  # when it was written

    assert page(one) == page(two)


def _run(capture, jobs=2):
    """A ParallelRun of a capture into JSONL (in memory): (run, bytes)."""
    import io

    from sniffer.capture.settings import CaptureSpec
    from sniffer.parallel.outputs import StreamPlan, StreamWriter
    from sniffer.parallel.run import ParallelRun
    from sniffer.sources.segset import capture_source

    out = io.BytesIO()
    run = ParallelRun(CaptureSpec(input=capture), capture_source(capture), [(StreamPlan("jsonl"), StreamWriter(out))],
                      jobs=jobs)
    run.run()
    return run, out.getvalue()


def _one(capsys, capture) -> bytes:
    capsys.readouterr()
    assert main(["replay", capture, "--format", "jsonl", "--jobs", "1"]) == 0
    return capsys.readouterr().out.encode()


def test_a_part_decoded_from_a_stale_scale_is_decoded_again(capsys, small_parts, captures):
    """Cn-02 changes mid-capture: the parts handed out before the change was known read the old value from
    their guess; each is checked when its turn comes and decoded again from the truth."""
    run, data = _run(captures["scaling"])
    assert run.engine.redone >= 1
    assert data == _one(capsys, captures["scaling"])


def test_a_finished_file_is_read_by_the_workers_and_a_damaged_chunk_by_the_reader(capsys, small_parts, captures):
    """The workers read a finished MCAP's chunks themselves; where a chunk fails its CRC the coordinator reads
    the rest with the file's reader, which skips the chunk and says so, as one process does."""
    run, data = _run(captures["errors"])
    assert not run.engine.switched and isinstance(run.engine._store, type(run.engine._store))  # noqa: SLF001
    capsys.readouterr()
    run, data = _run(captures["damaged"])
    assert run.engine.switched and run.damage
    rc = main(["replay", captures["damaged"], "--format", "jsonl", "--jobs", "1"])
    assert rc == 2 and data == capsys.readouterr().out.encode()


def test_a_line_never_quiet_is_decoded_in_order_from_its_last_quiet_point(capsys, small_parts, captures):
    run, data = _run(captures["dead"])
    assert run.engine.tail
    assert data == _one(capsys, captures["dead"])


def test_what_a_part_cannot_carry_keeps_one_process_and_says_so(capfd, tmp_path, captures):
    rc, out, err = _cli(capfd, "replay", captures["errors"], "--jobs", "2", "--trigger", "crc", "--windows", tmp_path)
    assert rc == 0, err
    assert "note: --jobs 2: one process (--trigger" in err
    assert out


def test_jobs_takes_a_number_of_processes(capfd, captures):
    rc, _out, err = _cli(capfd, "replay", captures["errors"], "--jobs", "0")
    assert rc == 2 and "--jobs 0 is outside 1..256" in err


@pytest.mark.parametrize("fmt", ["csv", "pcap", "mcap", "parquet"])
def test_a_file_that_cannot_be_made_fails_before_any_part_as_in_one_process(tmp_path, captures, fmt):
    """A full disk at the start (a file size limit of 0): one line, exit 2, nothing left, with --jobs 2 too."""
    import subprocess
    import sys

    code = ("import resource,sys; resource.setrlimit(resource.RLIMIT_FSIZE,(0,0));"
            "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN);"
            "from sniffer.cli import main; sys.exit(main(sys.argv[1:]))")
    got = []
    for jobs in ("1", "2"):
        r = subprocess.run([sys.executable, "-c", code, "export", captures["errors"], "--to", fmt, "--out",
                            f"x.{fmt}", "--jobs", jobs], capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert os.listdir(tmp_path) == []
        got.append(r.stderr)
    assert got[0] == got[1]


def test_a_missing_input_leaves_the_old_output_as_in_one_process(capfd, tmp_path):
    keep = tmp_path / "keep.pcap"
    keep.write_text("precious")
    rc, _out, err = _cli(capfd, "export", tmp_path / "nosuch.mcap", "--to", "pcap", "--out", keep, "--jobs", "2")
    assert rc == 2 and "no such file" in err
    assert keep.read_text() == "precious" and not list(tmp_path.glob("*.part"))


class _Calls:
    """A sink that keeps every call as one process makes it (raw events and frames, encoded)."""

    outputs = ()

    def __init__(self) -> None:
        self.calls: list = []
        self.t0 = 0

    def start(self, info) -> None:
        self.t0 = info.t0_ns

    def raw(self, ev) -> None:
        from sniffer.formats.mcap.format import encode_event

        self.calls.append(("raw", encode_event(ev)))

    def frame(self, f) -> None:
        from sniffer.formats.records import frame_json

        self.calls.append(("frame", frame_json(f, self.t0)))

    def close(self) -> None:
        self.calls.append("closed")


@pytest.mark.parametrize("name", ["scaling", "errors", "links", "rotated"])
def test_any_sink_run_in_the_coordinator_gets_the_calls_one_process_makes(small_parts, captures, name):
    """CallsPlan + SinkWriter: how a command runs a sink the parts cannot split (a diagnosis of the whole capture)."""
    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.parallel.outputs import CallsPlan, SinkWriter
    from sniffer.parallel.run import ParallelRun
    from sniffer.sources.segset import capture_source

    one, two = _Calls(), _Calls()
    Session(CaptureSpec(), capture_source(captures[name]), [one]).run()
    run = ParallelRun(CaptureSpec(), capture_source(captures[name]), [(CallsPlan(raw=True), SinkWriter(two))], jobs=2)
    run.run()
    assert one.calls == two.calls


@pytest.mark.parametrize("name", ["scaling", "errors", "dead"])
def test_closing_before_an_event_hands_on_what_the_event_would_have_first(captures, name):
    """Pipeline.close_before(ev) then feed(ev) give the frames feed(ev) alone gives, in the same order, at every
    event, and leave the pipelines alike wherever a part may start (the cut where a silence closes the framer's
    bytes)."""
    from decoders.registry import default_registry

    from sniffer.capture.session import CaptureSpec, Session
    from sniffer.formats.records import frame_record
    from sniffer.sources.segset import capture_source

    session = Session(CaptureSpec(), capture_source(captures[name]), [])
    info = session.open()
    res = session.resolved

    def pipeline():
        return res.pipeline(info, [], default_registry(res.devices))

    a, b = pipeline(), pipeline()
    closed = 0
    for ev in session.source.events():
        early = b.close_before(ev)
        closed += bool(early)
        got_a, got_b = a.feed(ev), early + b.feed(ev)
        assert [frame_record(f, 0) for f in got_a] == [frame_record(f, 0) for f in got_b]
        assert a.settled() == b.settled()
        if a.settled() == 2:  # where a part may start: nothing tells the two apart
            assert a.cut_state() == b.cut_state()
    if name != "errors":  # per-read times: a silence that closes bytes is rare there
        assert closed


def test_renumbering_moves_the_frames_and_the_numbers_the_notes_name():
    from sniffer import codes
    from sniffer.capture.pairer import renumber
    from sniffer.codes import note
    from sniffer.frame import Frame

    f = Frame(3, 0, 1, b"\x01\x03", "modbus-rtu", 1, 3)
    f.pair = 2
    f.annotations = [note(codes.RETRY, "repeats frame #1", 0, 2), note(codes.ORPHAN_RESPONSE, "nothing pending", 0, 2),
                     note(codes.ROLE_AMBIGUOUS, "taken as the response to #2 though x; as a request it would leave "
                                                "#2 unanswered", 0, 2)]
    renumber([f], 100)
    assert (f.index, f.pair) == (103, 102)
    assert [a.detail for a in f.annotations] == [
        "repeats frame #101", "nothing pending",
        "taken as the response to #102 though x; as a request it would leave #102 unanswered"]


def test_a_capture_without_events_is_its_own_part(capfd, tmp_path):
    """A capture with no event at all (a simulation of a millisecond, a segment killed at its start): its start
    is the cut, and every command gives what one process gives (it said 'no quiet point' and exit 1)."""
    from sniffer.cli import main

    empty = str(tmp_path / "empty.mcap")
    assert main(["simulate", "--duration", "0.001", "--out", empty]) == 0
    capfd.readouterr()
    _same(capfd, ["replay", empty, "--format", "jsonl"], ["replay", empty, "--format", "jsonl"])
    _same(capfd, ["diagnose", empty], ["diagnose", empty])
    one, two = str(tmp_path / "one.html"), str(tmp_path / "two.html")
    _same(capfd, ["report", empty, "--out", one], ["report", empty, "--out", two])
    _same(capfd, ["check", empty, "--golden", str(tmp_path / "one.txt"), "--update-golden"],
          ["check", empty, "--golden", str(tmp_path / "two.txt"), "--update-golden"], [str(tmp_path / "one.txt")])


def test_a_wrong_line_is_warned_of_as_one_process_does(capfd, tmp_path, small_parts):
    """The line warning of a replay by parts counts every frame in order from what the workers send of each
    (link, time, bytes, what made it bad), not the frames themselves: the same warning, at the same frame."""
    from sniffer.cli import main

    path = str(tmp_path / "wrong.mcap")
    assert main(["simulate", "--out", path, "--scenario", "default", "--duration", "20",
                 "--fault", "wrong_line_settings:38400"]) == 0
    capfd.readouterr()
    _same(capfd, ["replay", path, "--quiet"], ["replay", path, "--quiet"])
    rc, _out, err = _cli(capfd, "replay", path, "--quiet", "--jobs", "2")
    assert "probably wrong" in err and err.count("probably wrong") == 1, err
