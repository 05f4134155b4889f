"""`sniffer check CAPTURE --golden FILE`: exit 0 same, 1 different (a summary; --diff adds the unified diff),
2 error."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from sniffer.analysis.check import (
    EXIT_DIFFERENT, EXIT_ERROR, EXIT_SAME, Tolerances, golden_lines, golden_version,
    options_line, read_lines, resolve, FINDING, GOLDEN_HEADER, GOLDEN_V1,
)
from sniffer.analysis.checksummary import CheckSummary, summarize
from sniffer.analysis.goldenfields import NO_RULES, FieldRules, Names, parse_tolerance
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.flags import (
    UsageError, command_parser, decode_flags, duration, input_flags, jobs_flag, serial_flags,
)
from sniffer.diagnose import Diagnosis


def _tolerance(text: str):
    try:
        return parse_tolerance(text)
    except ValueError as e:
        raise UsageError(str(e)) from None


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "check", help="decode a capture and compare it with its golden text (exit 0 same, 1 diff)",
        description="""\
            Regression test for decoding: decode a capture and compare it, frame by frame, with its reviewed
            golden text (one line a frame; with --findings, `sniffer diagnose`'s verdicts after them).  Exit 0
            the same (`ok: N frames, M findings match` on stderr), 1 different (a summary on stdout: frames
            that differ, the first difference, the differences by unit and field, findings added or gone;
            --diff adds the unified diff), 2 an error.  --update-golden writes the golden: review its diff
            before you commit it.  --ignore, --tolerance and the time tolerances given with --update-golden
            are kept in the golden's header, so the next run uses them.""",
        examples=["sniffer check captures/a510.mcap --golden captures/golden/a510.txt --diff",
                  "sniffer check cab3.mcap --golden cab3.txt --findings --update-golden && git diff cab3.txt",
                  "sniffer check cab3.mcap --golden cab3.txt --tolerance 'Output current=0.2A' "
                  "--ignore 'Analog input*' --time-tol-ms 5 --update-golden",
                  "sniffer check cab3.mcap --golden cab3.txt --format json --junit check.xml"])
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
    p.add_argument("--time-tol-ms", type=tol, default=None, metavar="TIME",
                   help="frame time tolerance, in ms or with a unit (default: the golden's, else 1 ms)")
    p.add_argument("--latency-tol-ms", type=duration("--latency-tol-ms", bare="ms", unit="ms", upper_s=1e6),
                   default=None, metavar="TIME",
                   help="latency tolerance, in ms or with a unit (default: the golden's, else 1 ms)")
    p.add_argument("--ignore", action="append", default=[], metavar="FIELD",
                   help="leave this field out of the comparison: a point's name as the golden shows it "
                        "('Output current', 'holding[8451]'), a glob ('Analog input*'), or crc, pair, codes "
                        "(repeatable)")
    p.add_argument("--tolerance", action="append", default=[], type=_tolerance, metavar="FIELD=AMOUNT",
                   help="compare this field within AMOUNT: absolute in the field's unit ('Output current=0.2A') "
                        "or relative to the golden's value ('Output current=5%%') (repeatable)")
    p.add_argument("--diff", action="store_true", help="after the summary, the unified diff of the golden lines")
    p.add_argument("--format", choices=["text", "json"], default="text", help="the summary on stdout (json: "
                   "one object, also when the check passes)")
    p.add_argument("--junit", metavar="FILE.xml", help="also write the result as JUnit XML for a CI system "
                   "(a test case for the capture; the summary is the failure message)")
    jobs_flag(p)
    serial_flags(p, "file")
    decode_flags(p, "file")


@dataclass
class Outcome:
    """A check's result: the exit code, the summary (None for an error or an update) and the message."""

    rc: int
    summary: CheckSummary | None = None
    message: str = ""


def run(spec: CaptureSpec, args) -> int:
    from sniffer.commands.common import jobs_for

    import time

    started = time.monotonic()
    rules = FieldRules(tuple(args.ignore), tuple(args.tolerance))
    o = check_outcome(spec.input, args.golden, spec=spec, update=args.update_golden, findings=args.findings,
                      jobs=jobs_for(spec, args), time_ms=args.time_tol_ms, latency_ms=args.latency_tol_ms,
                      rules=rules, allow_unfinished=args.allow_unfinished)
    if args.junit:
        from sniffer.formats.junit import write_junit

        try:
            write_junit(args.junit, [(os.fspath(spec.input), o.rc, o.summary, o.message)],
                        inputs=[spec.input, args.golden], seconds=time.monotonic() - started)
        except (OSError, ValueError) as e:
            why = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) and e.filename else str(e)
            sys.stderr.write(f"sniffer check: error: --junit: {why}\n")
            return EXIT_ERROR
    if args.format == "json":
        import orjson

        d = o.summary.to_dict() if o.summary else {"golden": os.fspath(args.golden), "error": o.message.strip()}
        if o.summary and args.diff:
            d["diff"] = o.summary.diff
        sys.stdout.write(orjson.dumps(d, option=orjson.OPT_INDENT_2).decode() + "\n")
        if o.rc != EXIT_DIFFERENT and o.message:
            sys.stderr.write(o.message)
        return o.rc
    text = o.summary.text(args.diff) if o.rc == EXIT_DIFFERENT else o.message
    (sys.stdout if o.rc == EXIT_DIFFERENT else sys.stderr).write(text)
    return o.rc


def check(capture, golden, *, spec=None, tolerances: Tolerances | None = None, update: bool = False,
          findings: bool = False, jobs: int = 1, diff: bool = False, allow_unfinished: bool = False) -> tuple[int, str]:
    """(exit code, text): 0 same (`ok: ...`), 1 different (the summary; with `diff` the unified diff after it),
    2 error (one line).  `tolerances`: as given (else the golden header's, else the defaults)."""
    t = tolerances
    o = check_outcome(capture, golden, spec=spec, update=update, findings=findings, jobs=jobs,
                      time_ms=t.time_ms if t else None, latency_ms=t.latency_ms if t else None,
                      rules=t.rules if t else FieldRules(), allow_unfinished=allow_unfinished)
    if o.rc == EXIT_DIFFERENT:
        return o.rc, o.summary.text(diff)
    return o.rc, o.message


def check_outcome(capture, golden, *, spec=None, update: bool = False, findings: bool = False, jobs: int = 1,
                  time_ms: float | None = None, latency_ms: float | None = None,
                  rules: FieldRules = NO_RULES, allow_unfinished: bool = False) -> Outcome:
    """Check `capture` against `golden` (or rewrite it): the Outcome.  `findings`: the golden holds the capture's
    findings too (they are compared whenever the golden holds them).  `jobs` > 1: decoded by parts in that
    many processes (sniffer.parallel), the same lines.  A capture not closed cleanly (cut short) is said (the
    note `replay` prints); its golden is written only with `allow_unfinished`."""
    from decoders.registry import DeviceMapError

    from sniffer.events import CaptureError
    from sniffer.line import SettingsError

    golden = Path(golden)
    try:
        tol = resolve(golden, time_ms, latency_ms, rules)
        return _check(capture, golden, spec, tol, update, jobs, findings, allow_unfinished)
    except (CaptureError, SettingsError, DeviceMapError, ValueError, OSError) as e:
        why = f"{e.filename}: {e.strerror}" if isinstance(e, OSError) and e.filename else str(e)
        return Outcome(EXIT_ERROR, message=f"sniffer check: error: {why}\n")


def _no_golden(golden: Path) -> Outcome:
    return Outcome(EXIT_ERROR, message=f"sniffer check: error: {golden}: no such golden file "
                                       "(create it with --update-golden, then review it)\n")


def _names(capture, golden) -> tuple[str, str]:
    return os.fspath(golden), os.fspath(capture)


def _verdict(s: CheckSummary, err: str | None) -> Outcome:
    if err:
        return Outcome(EXIT_ERROR, message=f"sniffer check: error: {err}\n")
    if s.same:
        return Outcome(EXIT_SAME, s, s.ok_line())
    return Outcome(EXIT_DIFFERENT, s)


def _check(capture, golden: Path, spec, tol: Tolerances, update: bool, jobs: int,
           findings: bool, allow_unfinished: bool = False) -> Outcome:
    """The golden lines of the capture, in order (by parts in `jobs` processes or not: sniffer.decoding), compared
    with the golden or written as it; with the findings: the frames through one diagnosis here, then its
    findings."""
    from sniffer.decoding import decode_file
    from sniffer.formats.outputs import Output
    from sniffer.parallel.outputs import GoldenPlan

    run = decode_file(capture, spec, jobs=jobs)  # an unreadable capture is said first
    if not update and not golden.exists():
        run.close()
        return _no_golden(golden)
    version = 2 if update else golden_version(golden)
    findings = findings or (not update and holds_findings(golden))
    out = None
    if update:
        golden.parent.mkdir(parents=True, exist_ok=True)  # a new golden folder is part of --update-golden
        out = Output(golden, inputs=[capture, *(spec.read_paths() if spec else ())], what="--golden")
    header = GOLDEN_HEADER if version >= 2 else GOLDEN_V1
    names = Names()
    kept = options_line(tol) if update else None

    def lines():
        if findings:
            it = with_findings(run, golden_lines(run.info.t0_ns, diagnosed(run, _named(run, names)), version))
            yield next(it)
            if kept:
                yield kept
            yield from it
            return
        yield header
        if kept:
            yield kept
        for part_lines, part_names in run.pieces(GoldenPlan(version)):
            names.add_seen(part_names)
            yield from part_lines

    if out is None:
        s = summarize(read_lines(golden), lines(), tol, _names(capture, golden), names)
        err = _failed(run)
        if not err:
            _cut_short(run, True)
        return _verdict(s, err)
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
                d = summarize(read_lines(golden), new, Tolerances(0, 0), _names(capture, golden), names).diff
            for _ in new:  # decode what the comparison did not need
                pass
        err = _failed(run) or _cut_short(run, allow_unfinished)
    finally:
        if err:  # a golden from a damaged or failed decode would be wrong: keep the old one
            out.discard()
        else:
            out.commit()
    if err:
        return Outcome(EXIT_ERROR, message=f"sniffer check: error: {err}\n")
    return Outcome(EXIT_SAME, message=f"sniffer check: wrote {golden} ({run.frames_out} frames)\n" + d)


def _named(frames, names: Names):
    """The frames, their point names noted on the way (the anchors the summary splits a line on)."""
    for f in frames:
        names.add_frame(f)
        yield f


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
    from sniffer.decoding import note_unfinished, unfinished_paths

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
    """The run's frames (or `frames`), each through a diagnosis engine first (kept as `session.diagnosis`)."""
    engine = session.diagnosis = Diagnosis()
    engine.start_session(session)
    for f in session if frames is None else frames:
        engine.frame(f)
        yield f
