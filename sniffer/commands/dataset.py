"""Captures into a fleet dataset: what `sniffer export CAPTURE... --to dataset DIR` and `sniffer ingest` share.

Each capture is one segment: decoded by its own Session into its own files (sniffer.dataset.ingest),
taken in whole or not at all; one line per capture on stderr, then a total.  A capture the
dataset has already is skipped.  Exit 0 when every capture was taken in (or was there already),
2 when one could not be read (the others are taken in all the same), 1 when the dataset could
not be written.
"""

from __future__ import annotations

import os

from sniffer import need
from sniffer.dataset.ingest import Failed, Skipped, Taken, take_in, tidy
from sniffer.dataset.layout import Known, create_dataset
from sniffer.formats.outputs import shown
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_FAILED, EXIT_OK, EXIT_USAGE, UsageError, say


def export_dataset(spec: CaptureSpec, args, files: list[str], root: str) -> int:
    """export --to dataset: the captures named, in the order given.  A rotated capture's folder (or its
    index.json) is its closed segments, each a capture of the dataset as `ingest` takes them; a segment still
    open (or one a killed capture left) is named in a note and left for a later run."""
    need("fleet", "sniffer export --to dataset")
    return take_in_all(spec, args, [f for path in files for f in _captures_of(path)], root)


def _captures_of(path: str) -> list[str]:
    from sniffer.formats.mcap.segments import INDEX_NAME, set_files

    if not (os.path.isdir(path) or os.path.basename(path) == INDEX_NAME):
        return [path]
    segments = set_files([path])
    if not segments:
        raise UsageError(f"{shown(path)}: no capture files there (not a rotated capture's folder; "
                         f"sniffer ingest FOLDER --to DIR takes every .mcap under a folder)")
    for f in segments:
        if not f.endswith(".mcap"):
            say(f"note: {shown(f)}: not closed (the open segment, or one a killed capture left): not taken in; a "
                f"later run takes it in once it is closed (`sniffer repair` finishes a killed one)")
    return [f for f in segments if f.endswith(".mcap")]


def take_in_all(spec: CaptureSpec, args, files: list[str], root: str) -> int:
    """Each capture of `files` into the dataset at `root`, one line each, then the total; the exit code."""
    ds = create_dataset(root)
    for line in tidy(ds):  # what killed runs left
        say(f"note: {line}")
    known = Known(ds.manifest())
    taken = skipped = frames = replaced = 0
    failed: list[Failed] = []
    for result in _results(ds, spec, args, files, known):
        if isinstance(result, Taken):
            taken += 1
            replaced += bool(result.replaced)
            frames += result.entry["frames"]
            say(result.line())
        elif isinstance(result, Skipped):
            skipped += 1
            say(result.line())
        else:
            failed.append(result)
            say(f"error: {result.line()}")
    more = f", {len(failed)} not taken in (said above)" if failed else ""
    again = f" ({replaced} replacing an earlier version of their file)" if replaced else ""
    say(f"{shown(root)}: {taken} capture{'s' if taken != 1 else ''} taken in ({frames} frames){again}, "
        f"{skipped} already there{more}")
    if any(f.why.startswith(f"{shown(f.path)}: cannot write the dataset") for f in failed):
        return EXIT_FAILED
    return EXIT_USAGE if failed else EXIT_OK


def _results(ds, spec: CaptureSpec, args, files: list[str], known):
    """Each capture's result, in order: decoded here one by one, or by worker processes (--jobs) or a Dask cluster
    (--dask), each capture by one worker (sniffer.parallel.fleet: the same dataset)."""
    from sniffer.commands.common import jobs_for

    address = getattr(args, "dask", None)
    jobs = 1 if address else min(jobs_for(spec, args), len(files))
    if address or jobs > 1:
        from sniffer.parallel.fleet import DaskError, take_in_all

        try:
            yield from take_in_all(ds, files, spec, known, link=args.link, jobs=jobs, dask=address)
        except DaskError as e:
            raise UsageError(str(e)) from None
        return
    for path in files:
        bar = _bar(path, args) if getattr(args, "progress", False) else None
        try:
            yield take_in(ds, path, spec, known, link=args.link, on_event=bar.update if bar else None)
        finally:
            if bar is not None:
                bar.close()


def _bar(path: str, args):
    from sniffer.capture.progress import ReplayProgress

    return ReplayProgress(path)
