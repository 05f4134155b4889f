"""`sniffer check CAPTURE --golden FILE`: exit 0 same, 1 different (a unified diff on stdout), 2 error."""

from __future__ import annotations

import sys

import os
from pathlib import Path

from sniffer.analysis.check import (
    EXIT_DIFFERENT, EXIT_ERROR, EXIT_SAME, GOLDEN_HEADER, GOLDEN_V1, GoldenSink, Tolerances, compare_lines,
    golden_lines, golden_version, read_lines,
)
from sniffer.capture.settings import CaptureSpec


def cmd_check(spec: CaptureSpec, args) -> int:
    from sniffer.capture.settings import finite

    tol = Tolerances(finite(args.time_tol_ms, "--time-tol-ms", upper=1e9),
                     finite(args.latency_tol_ms, "--latency-tol-ms", upper=1e9))
    from sniffer.commands.common import jobs_for

    rc, text = check(spec.input, args.golden, spec=spec, update=args.update_golden, tolerances=tol,
                     jobs=jobs_for(spec, args))
    (sys.stdout if rc == 1 else sys.stderr).write(text)
    return rc


def check(capture, golden, *, spec=None, tolerances: Tolerances | None = None,
          update: bool = False, jobs: int = 1) -> tuple[int, str]:
    """(exit code, text): 0 same, 1 different (unified diff), 2 error (one line); `jobs` > 1: decoded by parts
    in that many processes (sniffer.parallel), the same lines."""
    if jobs > 1:
        return _check_parts(capture, golden, spec, tolerances or Tolerances(), update, jobs)
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
                new = golden_lines(session.info.t0_ns, session)
                d = ""
                if golden.exists():
                    d = compare_lines(read_lines(golden), new, Tolerances(0, 0), (name, os.fspath(capture)))
                for _ in new:  # decode what the comparison did not need
                    pass
                err = _failed(session)
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
        d = compare_lines(read_lines(golden), golden_lines(session.info.t0_ns, session, golden_version(golden)), tol,
                          (name, os.fspath(capture)))
        err = _failed(session)
        if err:
            return EXIT_ERROR, f"sniffer check: error: {err}\n"
    except (CaptureError, SettingsError, DeviceMapError, ValueError, OSError) as e:
        why = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) and e.filename else str(e)
        return EXIT_ERROR, f"sniffer check: error: {why}\n"
    return (EXIT_DIFFERENT, d) if d else (EXIT_SAME, "")


def _check_parts(capture, golden, spec, tol: Tolerances, update: bool, jobs: int) -> tuple[int, str]:
    """check() with the capture decoded by parts: the golden lines come from the workers, in order."""
    from decoders.registry import DeviceMapError

    from sniffer.line import SettingsError
    from sniffer.formats.outputs import Output
    from sniffer.events import CaptureError
    from sniffer.parallel.outputs import GoldenPlan
    from sniffer.parallel.run import decode_capture

    golden = Path(golden)
    names = (f"{golden}", os.fspath(capture))
    try:
        if not update and not golden.exists():
            return EXIT_ERROR, (f"sniffer check: error: {golden}: no such golden file "
                                "(create it with --update-golden, then review it)\n")
        version = 2 if update else golden_version(golden)
        out = None
        if update:
            golden.parent.mkdir(parents=True, exist_ok=True)
            out = Output(golden, inputs=[capture, *(spec.read_paths() if spec else ())], what="--golden")
        run = decode_capture(capture, spec, jobs)
        header = GOLDEN_HEADER if version >= 2 else GOLDEN_V1

        def lines():
            yield header
            for part in run.parts([GoldenPlan(version)]):
                yield from part.pieces[0]

        if out is None:
            d = compare_lines(read_lines(golden), lines(), tol, names)
            err = _failed(run)
            if err:
                return EXIT_ERROR, f"sniffer check: error: {err}\n"
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
            err = _failed(run)
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
