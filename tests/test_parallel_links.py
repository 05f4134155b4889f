"""--jobs 2 gives what --jobs 1 gives on captures of one, two and three links, findings included.

The links are simulated lines read through USB adapters (a timestamp per read): with two or
more such links some link is always mid-frame, so the capture has no quiet point to cut at
after its start and the coordinator decodes it in order (the streaming tail), while the
decoders' naming in the coordinator stays where the last part taken left it.  A command
whose verdicts look a unit's model up (a TDS-V8 that saves its parameters to EEPROM at every
cycle: `eeprom_wear`) must judge it by the model its frames were decoded with, in one process
as by parts.  A one-link capture of the same lines cuts into many parts.
"""

from __future__ import annotations

import io
import json
import os
import re

import pytest

from sniffer.cli import main
from sniffer.events import CaptureInfo, Chunk

LINES = {1: ("tds-v8",), 2: ("errors", "tds-v8"), 3: ("errors", "tds-v8", "a510")}


@pytest.fixture
def small_parts(monkeypatch):
    """Parts of 200 events: a one-link capture of 20 s has a dozen cuts."""
    import sniffer.parallel.engine as engine

    monkeypatch.setattr(engine, "PART_EVENTS", 200)
    monkeypatch.setattr(engine, "WARM_EVENTS", 16)
    monkeypatch.setattr(engine, "OVER_EVENTS", 128)


def _write_links(path, names, seconds: float) -> str:
    """A capture of len(names) links (a, b, c), each a simulated scenario read by a USB adapter."""
    from sniffer.capture.session import CaptureSpec, EventSource, Session
    from sniffer.formats import FileSink
    from sniffer.simulator import get_scenario, simulate, usb_chunks

    chunks, links = [], []
    for k, name in enumerate(names):
        sc = get_scenario(name)
        link = "abc"[k] if len(names) > 1 else ""
        for c in usb_chunks(simulate(sc, sc.line, seconds, 3 + k), seed=k):
            chunks.append(Chunk(c.t_ns, c.data, c.byte_t_ns, c.flags, "", link))
        line = sc.line
        links.append({"name": link, "baud": line.baud, "parity": line.parity, "stopbits": line.stopbits})
    chunks.sort(key=lambda c: c.t_ns)
    first = links[0]
    info = CaptureInfo(baud=first["baud"], parity=first["parity"], stopbits=first["stopbits"],
                       links=links if len(names) > 1 else [])
    Session(CaptureSpec(), EventSource(info, chunks), [FileSink("mcap", str(path), timed_flush=False)]).run()
    return str(path)


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    d = tmp_path_factory.mktemp("links")
    return {n: _write_links(d / f"links{n}.mcap", names, 25.0) for n, names in LINES.items()}


def _cli(capfd, *args) -> tuple[int, bytes, str]:
    capfd.readouterr()
    rc = main([str(a) for a in args])
    out, err = capfd.readouterr()
    return rc, out.encode(), err


def _when(data: bytes) -> bytes:
    """A report without the time it was written."""
    return re.sub(rb"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", b"T", data)


def _same(capfd, tmp_path, args: list, out: str | None = None, extra=()) -> tuple[bytes, dict]:
    """Run `args` with --jobs 1 and --jobs 2 (writing `out` as one.X and two.X): the exit code, stdout, stderr
    and every file (but the time a report was written) the same.  (stdout, {file: bytes}) of --jobs 1."""
    got = []
    for jobs, name in (("1", "one"), ("2", "two")):
        files = [str(tmp_path / f.replace("X", name)) for f in ([out] if out else []) + list(extra)]
        more = ["--out", files[0]] if out else []
        rc, stdout, stderr = _cli(capfd, *args, *more, "--jobs", jobs)
        written = {os.path.basename(f).replace(name, "X"): _when(open(f, "rb").read())
                   for f in files if os.path.exists(f)}
        got.append((rc, stdout.replace(b"one.", b"X.").replace(b"two.", b"X."),
                    stderr.replace("one.", "X.").replace("two.", "X."), written))
    assert got[0][0] == got[1][0] and got[0][2] == got[1][2], (got[0][2], got[1][2])
    assert got[0][1] == got[1][1]
    assert got[0][3].keys() == got[1][3].keys()
    for f, data in got[0][3].items():
        assert data == got[1][3][f], f
    return got[0][1], got[0][3]


@pytest.mark.parametrize("links", [1, 2, 3])
def test_diagnose_finds_what_one_process_finds(capfd, tmp_path, small_parts, captures, links):
    out, _ = _same(capfd, tmp_path, ["diagnose", captures[links], "--format", "json"])
    kinds = {(f["kind"], f["link"], f["unit"]) for f in json.loads(out)["findings"]}
    tds = None if links == 1 else "b"
    assert ("eeprom_wear", tds, 2) in kinds  # the TDS-V8 PLC saves unit 2's parameters every cycle
    _same(capfd, tmp_path, ["diagnose", captures[links]])


@pytest.mark.parametrize("links", [1, 2, 3])
def test_report_is_what_one_process_writes(capfd, tmp_path, small_parts, captures, links):
    _, files = _same(capfd, tmp_path, ["report", captures[links]], "X.html")
    assert b"eeprom_wear" in files["X.html"]


@pytest.mark.parametrize("links", [1, 2, 3])
@pytest.mark.parametrize("fmt", ["text", "jsonl"])
def test_replay_prints_what_one_process_prints(capfd, tmp_path, small_parts, captures, links, fmt):
    out, _ = _same(capfd, tmp_path, ["replay", captures[links], "--format", fmt])
    assert out.count(b"\n") > 500


class _Kept(io.BytesIO):
    """A stream whose bytes outlive close() (the pcap sink closes its stream)."""

    kept = b""

    def close(self) -> None:
        self.kept = self.getvalue()
        super().close()


@pytest.mark.parametrize("links", [1, 2, 3])
def test_a_stream_that_does_not_split_runs_in_the_coordinator_as_one_process_writes_it(small_parts, captures,
                                                                                     links):
    """`replay --format pcapng`'s stream (its header once, then packets in order) does not split: by parts it
    runs in the coordinator, fed the parts' frames and raw events, beside the line warning that does split.
    (In process: the CLI's pcapng stream closes stdout at its end.)"""
    from sniffer.capture.settings import CaptureSpec
    from sniffer.decoding import decode
    from sniffer.formats.pcap.writer import PcapSink
    from sniffer.parallel.run import ParallelRun
    from sniffer.sources.segset import capture_source

    got, said = [], []
    for jobs in (1, 2):
        from sniffer.analysis.linehealth import LineWarning

        out, lines = _Kept(), []
        spec = CaptureSpec(input=captures[links])
        run = decode(spec, capture_source(captures[links]), [LineWarning(lambda info, link: "", lines.append),
                                                            PcapSink(out, ng=True, comments=True)], jobs=jobs)
        assert isinstance(run, ParallelRun) == (jobs == 2)
        run.open()
        run.run()
        got.append(out.kept)
        said.append(lines)
    assert got[0][:4] == b"\x0a\x0d\x0d\x0a" and len(got[0]) > 10_000  # a Section Header Block first
    assert got[0] == got[1] and said[0] == said[1]


@pytest.mark.parametrize("links", [1, 2, 3])
@pytest.mark.parametrize("fmt", ["csv", "parquet", "mcap", "pcap", "pcapng", "jsonl"])
def test_export_writes_what_one_process_writes(capfd, tmp_path, small_parts, captures, links, fmt):
    points = ["X.points." + fmt] if fmt in ("csv", "parquet") else []
    _, files = _same(capfd, tmp_path, ["export", captures[links], "--to", fmt], f"X.{fmt}", points)
    assert len(files[f"X.{fmt}"]) > 10_000


@pytest.mark.parametrize("links", [1, 2, 3])
def test_check_and_its_findings_are_what_one_process_gives(capfd, tmp_path, small_parts, captures, links):
    one, two = tmp_path / "one.txt", tmp_path / "two.txt"
    for jobs, golden in (("1", one), ("2", two)):
        rc, _out, err = _cli(capfd, "check", captures[links], "--golden", golden, "--findings", "--update-golden",
                             "--jobs", jobs)
        assert rc == 0, err
    assert one.read_bytes() == two.read_bytes()
    assert any(line.startswith("finding ") and "eeprom_wear" in line for line in one.read_text().splitlines())
    _same(capfd, tmp_path, ["check", captures[links], "--golden", one])



@pytest.mark.parametrize("argv,parts", [
    (["replay", "{1}"], True),
    (["export", "{1}", "--to", "csv", "--out", "x.csv"], True),
    (["replay", "{2}"], False),  # several links: never quiet, decoded in order anyway
    (["replay", "{3}"], False),
    (["diagnose", "{1}"], False),  # bound by the one diagnosis in the coordinator
    (["report", "{1}", "--out", "r.html"], False),
    (["check", "{1}", "--golden", "g.txt"], False),
    (["export", "{1}", "--to", "mcap", "--out", "x.mcap"], False),
])
def test_without_jobs_parts_are_used_only_where_they_are_faster(monkeypatch, captures, argv, parts):
    import sniffer.parallel.options as options
    from sniffer.capture.settings import CaptureSpec
    from sniffer.cli import build_parser

    monkeypatch.setattr(options, "cores", lambda: 2)
    args = build_parser().parse_args([captures[int(a[1])] if a[0] == "{" else a for a in argv])
    spec = CaptureSpec.from_args(args)
    monkeypatch.setattr(options, "MIN_PARTS_BYTES", 1)
    assert options.default_jobs(spec, args) == (2 if parts else 1)
    monkeypatch.setattr(options, "MIN_PARTS_BYTES", os.path.getsize(captures[1]) + 1)  # a small capture
    assert options.default_jobs(spec, args) == 1
