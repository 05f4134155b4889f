"""`sniffer check CAPTURE --golden FILE`: exit 0 same, 1 different (a unified diff on stdout), 2 error."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path

from sniffer.analysis.check import (
    EXIT_DIFFERENT, EXIT_ERROR, EXIT_SAME, GoldenSink, Tolerances, compare_lines, golden_lines, golden_version,
    read_lines, FINDING, GOLDEN_HEADER, GOLDEN_V1,
)
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.flags import command_parser, decode_flags, duration, input_flags, jobs_flag, serial_flags
from sniffer.diagnose import Diagnosis


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "check", help="decode a capture and compare it with its golden text (exit 0 same, 1 diff)",
        description="""\
            Regression test for decoding: decode a capture and compare it, frame by frame, with its reviewed
            golden text (one line a frame; with --findings, `sniffer diagnose`'s verdicts after them).  Exit 0
            the same, 1 different (a unified diff on stdout), 2 an error.  --update-golden writes the golden:
            review its diff before you commit it.""",
        examples=["sniffer check captures/a510.mcap --golden captures/golden/a510.txt",
                  "sniffer check cab3.mcap --golden cab3.txt --update-golden && git diff cab3.txt",
                  "sniffer check cab3.mcap --golden cab3.txt --findings --update-golden",
                  "sniffer check cab3.mcap --golden cab3.txt --time-tol-ms 5"])
    input_flags(p)
    p.add_argument("--golden", required=True, metavar="FILE.txt", help="the reviewed golden decode")
    p.add_argument("--update-golden", action="store_true", help="rewrite the golden (review the diff!)")
    p.add_argument("--allow-unfinished", action="store_true",
                   help="with --update-golden: write the golden of a capture that was not closed cleanly (killed, "
                        "or still being written: its frames up to the cut); without it, such a golden is refused")
    p.add_argument("--findings", action="store_true",
                   help="the golden holds the capture's findings (`sniffer diagnose`'s verdicts) after its frames: "
                        "written with --update-golden, compared whenever the golden holds them")
    tol = duration("--time-tol-ms", bare="ms", unit="ms", upper_s=1e6)
    p.add_argument("--time-tol-ms", type=tol, default=1.0, metavar="TIME",
                   help="frame time tolerance, in ms or with a unit (default 1 ms)")
    p.add_argument("--latency-tol-ms", type=duration("--latency-tol-ms", bare="ms", unit="ms", upper_s=1e6),
                   default=1.0, metavar="TIME", help="latency tolerance, in ms or with a unit (default 1 ms)")
    jobs_flag(p)
    serial_flags(p, "file")
    decode_flags(p, "file")


def run(spec: CaptureSpec, args) -> int:
    tol = Tolerances(args.time_tol_ms, args.latency_tol_ms)
    from sniffer.commands.common import jobs_for

    rc, text = check(spec.input, args.golden, spec=spec, update=args.update_golden, tolerances=tol,
                     findings=args.findings, jobs=jobs_for(spec, args), allow_unfinished=args.allow_unfinished)
    (sys.stdout if rc == 1 else sys.stderr).write(text)
    return rc


def check(capture, golden, *, spec=None, tolerances: Tolerances | None = None,
          update: bool = False, findings: bool = False, jobs: int = 1, allow_unfinished: bool = False
          ) -> tuple[int, str]:
    """(exit code, text): 0 same, 1 different (unified diff), 2 error (one line).  `findings`: the golden holds
    the capture's findings too (they are compared whenever the golden holds them).  `jobs` > 1: decoded by
    parts in that many processes (sniffer.parallel), the same lines.  A capture not closed cleanly (cut short)
    is said (the note `replay` prints); its golden is written only with `allow_unfinished`."""
    if jobs > 1:
        return _check_parts(capture, golden, spec, tolerances or Tolerances(), update, jobs, findings,
                            allow_unfinished)
    from decoders.registry import DeviceMapError

    from sniffer.line import SettingsError
    from sniffer.formats.outputs import Output
    from sniffer.capture.session import decode_capture
    from sniffer.events import CaptureError

    tol = tolerances or Tolerances()
    golden = Path(golden)
    name = f"{golden}"
    try:
        if update:
            golden.parent.mkdir(parents=True, exist_ok=True)  # a new golden folder is part of --update-golden
            out = Output(golden, inputs=[capture, *(spec.read_paths() if spec else ())], what="--golden")
            sink = GoldenSink(out)
            err = "interrupted"
            try:
                session = decode_capture(capture, spec, [sink])
                if findings:
                    new = with_findings(session, golden_lines(session.info.t0_ns, diagnosed(session)))
                    sink.session = session
                else:
                    new = golden_lines(session.info.t0_ns, session)
                d = ""
                if golden.exists():
                    d = compare_lines(read_lines(golden), new, Tolerances(0, 0), (name, os.fspath(capture)))
                for _ in new:  # decode what the comparison did not need
                    pass
                err = _failed(session) or _cut_short(session, allow_unfinished)
            finally:
                sink.close()
                if err:  # a golden from a damaged or failed decode would be wrong: keep the old one
                    out.discard()
                else:
                    out.commit()
            if err:
                return EXIT_ERROR, f"sniffer check: error: {err}\n"
            return EXIT_SAME, f"sniffer check: wrote {golden} ({session.frames_out} frames)\n" + d
        session = decode_capture(capture, spec)
        if not golden.exists():
            session.close()
            return EXIT_ERROR, (f"sniffer check: error: {golden}: no such golden file "
                                "(create it with --update-golden, then review it)\n")
        if findings or holds_findings(golden):
            new = with_findings(session, golden_lines(session.info.t0_ns, diagnosed(session), golden_version(golden)))
        else:
            new = golden_lines(session.info.t0_ns, session, golden_version(golden))
        d = compare_lines(read_lines(golden), new, tol, (name, os.fspath(capture)))
        err = _failed(session)
        if err:
            return EXIT_ERROR, f"sniffer check: error: {err}\n"
        _cut_short(session, True)
    except (CaptureError, SettingsError, DeviceMapError, ValueError, OSError) as e:
        why = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) and e.filename else str(e)
        return EXIT_ERROR, f"sniffer check: error: {why}\n"
    return (EXIT_DIFFERENT, d) if d else (EXIT_SAME, "")


def _check_parts(capture, golden, spec, tol: Tolerances, update: bool, jobs: int,
                 findings: bool, allow_unfinished: bool = False) -> tuple[int, str]:
    """check() with the capture decoded by parts: the golden lines come from the workers, in order (with the
    findings: the frames, through one diagnosis here, then its findings)."""
    from decoders.registry import DeviceMapError

    from sniffer.line import SettingsError
    from sniffer.formats.outputs import Output
    from sniffer.events import CaptureError
    from sniffer.parallel.outputs import FramesPlan, GoldenPlan
    from sniffer.parallel.run import decode_capture

    golden = Path(golden)
    names = (f"{golden}", os.fspath(capture))
    try:
        if not update and not golden.exists():
            return EXIT_ERROR, (f"sniffer check: error: {golden}: no such golden file "
                                "(create it with --update-golden, then review it)\n")
        version = 2 if update else golden_version(golden)
        findings = findings or (not update and holds_findings(golden))
        out = None
        if update:
            golden.parent.mkdir(parents=True, exist_ok=True)
            out = Output(golden, inputs=[capture, *(spec.read_paths() if spec else ())], what="--golden")
        run = decode_capture(capture, spec, jobs)
        header = GOLDEN_HEADER if version >= 2 else GOLDEN_V1

        def lines():
            if findings:
                frames = (f for part in run.parts([FramesPlan()]) for f in part.pieces[0])
                yield from with_findings(run, golden_lines(run.info.t0_ns, diagnosed(run, frames), version))
                return
            yield header
            for part in run.parts([GoldenPlan(version)]):
                yield from part.pieces[0]

        if out is None:
            d = compare_lines(read_lines(golden), lines(), tol, names)
            err = _failed(run)
            if err:
                return EXIT_ERROR, f"sniffer check: error: {err}\n"
            _cut_short(run, True)
            return (EXIT_DIFFERENT, d) if d else (EXIT_SAME, "")
        err = "interrupted"
        try:
            with open(out.claim(), "w", encoding="utf-8") as fh:
                def written():
                    for line in lines():
                        fh.write(line + "\n")
                        yield line

                new = written()
                d = ""
                if golden.exists():
                    d = compare_lines(read_lines(golden), new, Tolerances(0, 0), names)
                for _ in new:
                    pass
            err = _failed(run) or _cut_short(run, allow_unfinished)
        finally:
            if err:
                out.discard()
            else:
                out.commit()
        if err:
            return EXIT_ERROR, f"sniffer check: error: {err}\n"
        return EXIT_SAME, f"sniffer check: wrote {golden} ({run.frames_out} frames)\n" + d
    except (CaptureError, SettingsError, DeviceMapError, ValueError, OSError) as e:
        why = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) and e.filename else str(e)
        return EXIT_ERROR, f"sniffer check: error: {why}\n"


def _failed(session) -> str | None:
    """Why a decode cannot be trusted (input error or damage), or None."""
    if session.error:
        return session.error
    if session.damage:
        return f"{session.damage[0]} (input damaged: {len(session.damage)} problem(s))"
    return None


def _cut_short(session, allowed: bool) -> str | None:
    """A capture not closed cleanly: its note (as `replay` says it), and unless `allowed`, why its golden is not
    written (a golden of the frames up to a cut would pass later checks of the same cut file, and miss the rest)."""
    from sniffer.commands.replay import note_unfinished, unfinished_paths

    paths = unfinished_paths(session)
    if not paths:
        return None
    note_unfinished(session)
    if allowed:
        return None
    return (f"{paths[0]}: not closed cleanly (cut short): no golden written from it; give --allow-unfinished to "
            "write the golden of the frames up to the cut")


def holds_findings(path: Path) -> bool:
    return any(line.startswith(FINDING) for line in read_lines(path))


def with_findings(session, lines: Iterator[str]) -> Iterator[str]:
    """The golden lines, then the findings of the frames they went through (sniffer.diagnose)."""
    yield from lines
    yield from (f.golden_line() for f in session.diagnosis.findings())


def diagnosed(session, frames=None):
    """The session's frames (or `frames`, a parallel run's), each through a diagnosis engine first (kept as
    `session.diagnosis`)."""
    engine = session.diagnosis = Diagnosis()
    engine.start_session(session)
    for f in session if frames is None else frames:
        engine.frame(f)
        yield f
