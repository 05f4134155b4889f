"""`--jobs N`: declared once here (`add_jobs_flag`), read by `jobs_of`; and why a run stays in one process.

    jobs = jobs_of(args)                     # N, or the machine's cores; 1: one process
    why = one_process_why(spec, args)        # None, or the one line that says why one process decodes it

A capture is decoded by parts only where the output is then the same as one
process's.  The things a part cannot carry across its cut (a trigger window's
pre-trigger ring, an MQTT broker's session, the TUI, a status file, re-cut
segments) keep one process, said in one line on stderr.
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
                   help="decode with N processes (default: the machine's cores; 1: one process); the output is "
                        "the same as with one (docs/parallel.md)")


def add_dask_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dask", metavar="ADDRESS",
                   help="decode the captures on a Dask cluster (its scheduler, e.g. tcp://host:8786), one capture "
                        "per task; its workers must see the captures and the dataset at the same paths")


def jobs_of(args) -> int:
    """The number of processes asked for (default: the cores this process may use)."""
    n = getattr(args, "jobs", None)
    return cores() if n is None else n


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
