"""One way to decode a capture file: `decode()` gives a run, in one process or by parts, with one interface.

    run = decode(spec, source, [FileSink("csv", "x.csv", inputs=[...])], jobs=jobs, progress=spec.input)
    run.open()                      # the source opened, the settings resolved, the outputs made (idempotent)
    run.run()                       # every frame into the sinks; or `for f in run:` (every frame, in order),
                                    # or `for piece in run.pieces(plan):` (a part plan's pieces, in order)
    report(run, label=...)          # frames_out, error, damage, notes, outputs: whatever ran it

`jobs` > 1 decodes by parts in worker processes (sniffer.parallel.run.ParallelRun), else
one capture session (sniffer.capture.session.Session); both are a `Run`.  A sink says
how it splits into parts (`Sink.split`, sniffer.parallel.outputs.SPLITS); a sink that
does not split runs in the coordinator, and a run whose sinks all run there runs in one
process (parts would only add work).  The run owns the progress bar (`progress`: the
capture's label) and the note for an input file not closed cleanly (`notes`), said when
the run opens and again when it ends (a rotated capture's segments open as the reading
reaches them), each file once.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from typing import Protocol, runtime_checkable

from sniffer.capture.session import Session
from sniffer.capture.settings import CaptureSpec
from sniffer.events import CaptureInfo
from sniffer.frame import Frame
from sniffer.stderr import say


@runtime_checkable
class Run(Protocol):
    """What every offline command drives (Session and ParallelRun both are one)."""

    spec: CaptureSpec
    source: object
    info: CaptureInfo | None
    error: str | None
    storage_error: bool
    interrupted: bool
    keep_partial: bool
    hooks: list

    @property
    def frames_out(self) -> int: ...

    @property
    def damage(self) -> list[str]: ...

    @property
    def notes(self) -> list[str]: ...

    @property
    def outputs(self) -> list: ...

    def open(self) -> CaptureInfo: ...

    def run(self) -> Run: ...

    def __iter__(self) -> Iterator[Frame]: ...

    def pieces(self, plan) -> Iterator: ...

    def close(self) -> None: ...


def decode(spec: CaptureSpec, source, sinks: Iterable = (), *, jobs: int = 1, progress: str | None = None,
           notes: bool = True, label: str = "", need_baud: bool = True) -> Run:
    """The run of `source` into `sinks` (see the module doc); not opened yet.  `need_baud=False`: a source
    without timing (hex frames typed in) decodes without a baud rate."""
    sinks = list(sinks)
    if jobs > 1 and sinks and all(split_of(s) is None for s in sinks):
        jobs = 1  # every sink would run in the coordinator: the workers would only add work
    if jobs > 1:
        from sniffer.parallel.run import ParallelRun

        run = ParallelRun(spec, source, sinks, jobs=jobs, label=label)
    else:
        run = Session(spec, source, sinks, label=label, need_baud=need_baud)
    if notes:
        run.hooks.append(UnfinishedNotes())
    if progress is not None:
        from sniffer.capture.progress import ReplayProgress

        bar = ReplayProgress(progress, source=source, frames=lambda: run.frames_out)
        run.on_event = bar.update
        run.hooks.append(_Bar(bar))
    return run


def decode_file(path: str | os.PathLike[str], spec: CaptureSpec | None = None, sinks: Iterable = (), *,
                jobs: int = 1, notes: bool = False) -> Run:
    """An opened run over a capture file (a folder of segments too): iterate it for its decoded frames.

    `.info` is the capture's metadata with the settings used; CaptureError / SettingsError (one line) for
    unreadable input or impossible settings.
    """
    from sniffer.sources.segset import capture_source

    spec = spec or CaptureSpec()
    whole = spec.inputs if spec.inputs and spec.input == os.fspath(path) else os.fspath(path)  # check's set
    run = decode(spec, capture_source(whole, spec.input_format, spec.logic), sinks, jobs=jobs, notes=notes)
    run.open()
    return run


def split_of(sink) -> str | None:
    """How a sink (or a planned file, sniffer.formats.FileSink) splits into parts; None: it runs whole."""
    return getattr(sink, "split", None)


class _Bar:
    """The progress bar, closed when the run ends (whatever ended it)."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def opened(self, run) -> None:
        pass

    def ended(self, run) -> None:
        self.bar.close()


class UnfinishedNotes:
    """A note for each input file not closed cleanly, once (see the module doc)."""

    def __init__(self) -> None:
        self.said: set[str] = set()

    def opened(self, run) -> None:
        self.say(run)

    def ended(self, run) -> None:
        self.say(run)

    def say(self, run) -> None:
        for path in unfinished_paths(run):
            if path in self.said:
                continue
            self.said.add(path)
            say(f"note: {path} was not closed cleanly (capture killed, or still being written?); read up to its "
                f"last complete record. 'sniffer repair {path}' writes a clean copy.")


def unfinished_paths(run) -> list[str]:
    """The input files of a run not closed cleanly, as read so far."""
    paths = list(getattr(run.source, "unfinished", None) or ())
    if not paths and run.info is not None and run.info.extra.get("mcap_unfinished"):
        paths = [run.spec.input]
    return paths


def note_unfinished(run) -> None:
    """Say the unfinished inputs of `run` now (once each, with the run's own notes if it has them)."""
    notes = next((h for h in run.hooks if isinstance(h, UnfinishedNotes)), None)
    if notes is None:
        notes = UnfinishedNotes()
        run.hooks.append(notes)
    notes.say(run)


__all__ = ["Run", "UnfinishedNotes", "decode", "decode_file", "note_unfinished", "split_of", "unfinished_paths"]
