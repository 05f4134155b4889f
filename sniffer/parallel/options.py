"""`--jobs N`: declared once here (`add_jobs_flag`), read by `jobs_of`; and why a run stays in one process.

    jobs = jobs_of(args)                     # N, or the machine's cores; 1: one process
    why = one_process_why(spec, args)        # None, or the one line that says why one process decodes it
    jobs = default_jobs(spec, args)          # no --jobs: parts only where they are faster
    jobs = jobs_for(spec, args)              # what a command runs with: the above, said in one line

A capture is decoded by parts only where the output is then the same as one
process's.  The things a part cannot carry across its cut (a trigger window's
pre-trigger ring, an MQTT broker's session, the TUI, a status file, re-cut
segments) keep one process, said in one line on stderr.

Without --jobs, parts are used only where they were measured faster than one
process (benchmarks/bench_jobs_default.py): not for a command bound by what its
coordinator does alone (one diagnosis, one report page, the golden's lines in
order, one MCAP file rewritten), not for a small capture (the workers' start
costs more than they save), and not for a capture of several links (with
per-read timestamps some link is always mid-frame: no quiet point to cut at, the
whole decoded in order in the coordinator behind the workers' wasted starts).
"""

from __future__ import annotations

import argparse
import os

MIN_JOBS, MAX_JOBS = 1, 256


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _jobs(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--jobs {text[:40]!r} is not a whole number") from None
    if not MIN_JOBS <= n <= MAX_JOBS:
        raise argparse.ArgumentTypeError(f"--jobs {n} is outside {MIN_JOBS}..{MAX_JOBS}")
    return n


def add_jobs_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--jobs", "-j", type=_jobs, default=None, metavar="N",
                   help="decode with N processes (default: the machine's cores where that was measured faster, "
                        "else one; 1: one process); the output is the same as with one (docs/parallel.md)")


def add_dask_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dask", metavar="ADDRESS",
                   help="decode the captures on a Dask cluster (its scheduler, e.g. tcp://host:8786), one capture "
                        "per task; its workers must see the captures and the dataset at the same paths")


def jobs_of(args) -> int:
    """The number of processes asked for (default: the cores this process may use)."""
    n = getattr(args, "jobs", None)
    return cores() if n is None else n


# decoded by parts these gained 1.10-1.17x for twice the CPU and 2-3x the memory (2 cores, a quiet machine):
# their coordinator does the work alone (the diagnosis, the report page, the golden's lines, the MCAP writer)
COORDINATOR_BOUND = frozenset({("report", None), ("diagnose", None), ("check", None), ("export", "mcap")})
MIN_PARTS_BYTES = 8_000_000  # smaller captures: starting the workers costs about what they save


def default_jobs(spec, args=None) -> int:
    """The processes a command runs with when --jobs is not given: the cores where parts are faster, else 1."""
    n = cores()
    if n == 1:
        return 1
    cmd, to = getattr(args, "cmd", None), getattr(args, "to", None)
    if cmd == "ingest" or to == "dataset":
        return n  # one capture a process (sniffer.parallel.fleet), not parts of one
    if (cmd, None) in COORDINATOR_BOUND or (cmd, to) in COORDINATOR_BOUND:
        return 1
    paths = list(spec.inputs or ([spec.input] if spec.input else []))
    if not paths or _bytes(paths) < MIN_PARTS_BYTES:
        return 1
    if len(spec.links or ()) > 1 or _links(spec) > 1:
        return 1
    return n


def _bytes(paths) -> int:
    total = 0
    for p in paths:
        try:
            if os.path.isdir(p):
                total += sum(e.stat().st_size for e in os.scandir(p) if e.is_file())
            else:
                total += os.path.getsize(p)
        except OSError:
            pass
    return total


def _links(spec) -> int:
    """How many links the capture holds (its header: cheap); 1 when it cannot be told."""
    from sniffer.capture.session import close_source
    from sniffer.sources.segset import capture_source

    try:
        source = capture_source(spec.inputs or spec.input, spec.input_format or "auto", spec.logic)
    except Exception:  # noqa: BLE001 - the command itself says what is wrong with its input
        return 1
    try:
        info = source.open()
        return max(1, len(info.links or ()))
    except Exception:  # noqa: BLE001 - as above
        return 1
    finally:
        try:
            close_source(source)
        except Exception:  # noqa: BLE001 - as above
            pass


def jobs_for(spec, args) -> int:
    """The processes a decoding command runs with (sniffer.decoding.decode): --jobs, else `default_jobs`; 1 where
    a part cannot carry what the command needs across its cut (said in one line when --jobs asked for more)."""
    from sniffer.stderr import say

    jobs = jobs_of(args) if getattr(args, "jobs", None) else default_jobs(spec, args)
    if jobs > 1:
        why = one_process_why(spec, args)
        if why:
            if getattr(args, "jobs", None):
                say(f"note: --jobs {jobs}: one process ({why})")
            return 1
    return jobs


def one_process_why(spec, args=None) -> str | None:
    """Why this command decodes in one process whatever --jobs says, or None."""
    if getattr(args, "tui", False):
        return "the TUI"
    if spec.trigger is not None:
        return "--trigger (a window's pre-trigger ring spans the parts)"
    if spec.mqtt is not None:
        return "--mqtt (one broker session, values in capture order)"
    if spec.rotate is not None:
        return "--rotate (segments are cut where one capture session is settled)"
    if spec.status:
        return "--status (one status file, updated as the capture goes)"
    if spec.publish:
        return "--publish"
    return None
