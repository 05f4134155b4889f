"""sniffer.decoding: one entry point for every offline command, one Run interface whether the capture is decoded
in one process or by parts; the Sink hooks the session calls, declared on the base class."""

from __future__ import annotations

import ast
import pathlib

import pytest

from sniffer.capture.session import CaptureSpec, EventSource, Session
from sniffer.decoding import Run, decode, decode_file
from sniffer.sinks.base import Sink, overrides


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    from sniffer.events import CaptureInfo
    from sniffer.formats import FileSink
    from sniffer.simulator import get_scenario, simulate, usb_chunks

    sc = get_scenario("tds-v8")
    path = str(tmp_path_factory.mktemp("decoding") / "tds.mcap")
    info = CaptureInfo(baud=sc.line.baud, parity=sc.line.parity, stopbits=sc.line.stopbits)
    Session(CaptureSpec(), EventSource(info, usb_chunks(simulate(sc, sc.line, 20.0, 5), seed=1)),
            [FileSink("mcap", path, timed_flush=False)]).run()
    return path


@pytest.fixture
def small_parts(monkeypatch):
    import sniffer.parallel.engine as engine

    monkeypatch.setattr(engine, "PART_EVENTS", 200)
    monkeypatch.setattr(engine, "WARM_EVENTS", 16)
    monkeypatch.setattr(engine, "OVER_EVENTS", 128)


@pytest.mark.slow  # worker processes
def test_one_process_and_parts_are_both_a_run_and_give_the_same_frames(capture, small_parts):
    from sniffer.formats.records import frame_record
    from sniffer.parallel.run import ParallelRun

    one, two = decode_file(capture, jobs=1), decode_file(capture, jobs=2)
    assert isinstance(one, Session) and isinstance(two, ParallelRun)
    assert isinstance(one, Run) and isinstance(two, Run)
    a = [frame_record(f, one.info.t0_ns) for f in one]
    b = [frame_record(f, two.info.t0_ns) for f in two]
    assert len(a) > 500 and a == b
    assert one.frames_out == two.frames_out == len(a)


@pytest.mark.slow  # worker processes
def test_pieces_of_a_plan_are_the_same_in_one_process_and_by_parts(capture, small_parts):
    """Session.pieces(plan) cuts what one process decodes into a plan's pieces: check reads both the same way."""
    from sniffer.parallel.outputs import GoldenPlan

    def lines(run):
        pieces = [got for got, _names in run.pieces(GoldenPlan())]
        return len(pieces), [line for got in pieces for line in got]

    (_, one), (n2, two) = lines(decode_file(capture, jobs=1)), lines(decode_file(capture, jobs=2))
    assert len(one) > 500 and one == two
    assert n2 > 3  # it really ran by parts


def test_a_run_whose_sinks_all_run_in_the_coordinator_runs_in_one_process(capture):
    import io

    from sniffer.formats.pcap.writer import PcapSink
    from sniffer.sources.segset import capture_source

    run = decode(CaptureSpec(input=capture), capture_source(capture), [PcapSink(io.BytesIO(), ng=True)], jobs=2)
    assert isinstance(run, Session)  # parts would only add work
    run = decode(CaptureSpec(input=capture), capture_source(capture), [], jobs=2)
    assert not isinstance(run, Session)  # no sink: the frames are wanted here, by parts


@pytest.mark.slow  # worker processes
def test_the_progress_bar_closes_when_the_run_ends_whoever_ran_it(capture, small_parts, monkeypatch):
    import sniffer.capture.progress as progress
    from sniffer.sources.segset import capture_source

    closed = []
    monkeypatch.setattr(progress.ReplayProgress, "close", lambda self: closed.append(self))
    for jobs in (1, 2):
        run = decode(CaptureSpec(input=capture), capture_source(capture), [], jobs=jobs, progress=capture)
        run.open()
        assert not closed
        for _ in run:
            pass
        assert len(closed) == 1
        closed.clear()


class _Clock(Sink):
    def __init__(self) -> None:
        self.times: list[int] = []
        self.bound = None

    def bind(self, pipeline) -> None:
        self.bound = pipeline

    def advance(self, t_ns: int) -> None:
        self.times.append(t_ns)


class _Plain:
    """A sink with only the four calls (a test's list): the session asks it nothing else."""

    def __init__(self) -> None:
        self.frames = 0

    def start(self, info) -> None:
        pass

    def raw(self, event) -> None:
        pass

    def frame(self, f) -> None:
        self.frames += 1

    def close(self) -> None:
        pass


def test_the_session_calls_a_hook_only_on_the_sinks_that_override_it(capture):
    from sniffer.sources.segset import capture_source

    clock, plain = _Clock(), _Plain()
    run = decode(CaptureSpec(input=capture), capture_source(capture), [clock, plain]).run()
    assert clock.bound is run.pipeline
    assert len(clock.times) > 500 and clock.times == sorted(clock.times)
    assert plain.frames == run.frames_out
    assert overrides(clock, "advance") and not overrides(clock, "maybe_flush") and not overrides(plain, "advance")


def test_every_hook_the_session_calls_is_declared_on_the_sink_base_class():
    """No sink hook is probed for with hasattr/getattr in the session: each is a method of Sink."""
    src = pathlib.Path(__file__).parents[1] / "sniffer" / "capture" / "session.py"
    called = set()
    for node in ast.walk(ast.parse(src.read_text())):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr", "getattr"):
            arg = node.args[0]
            if isinstance(arg, ast.Name) and arg.id in ("s", "sink"):
                called.add(ast.literal_eval(node.args[1]))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "overrides":
            assert hasattr(Sink, ast.literal_eval(node.args[1]))
    assert called == set()


def test_no_command_branches_on_jobs():
    """--jobs is handed to sniffer.decoding.decode; no command chooses an engine by it."""
    root = pathlib.Path(__file__).parents[1] / "sniffer" / "commands"
    for path in root.glob("*.py"):
        if path.name == "dataset.py":  # a fleet's captures, one per process (sniffer.parallel.fleet): not parts
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Compare):
                names = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)}
                assert "jobs" not in names, f"{path.name}:{node.lineno} compares jobs"
