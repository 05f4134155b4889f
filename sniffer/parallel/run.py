"""A capture decoded by parts in worker processes, with what a capture session gives its command.

    run = ParallelRun(spec, source, [(plan, writer), ...], jobs=4)
    run.open()                      # the source opened and the settings resolved, as Session.open
    run.run()                       # the parts decoded, their pieces written in order
    report(run, label=...)          # frames_out, bytes_in, error, damage, notes, outputs: as a Session's

A writer (sniffer.parallel.outputs) takes a plan's pieces in capture order; its
`outputs` (files under temporary names) are committed when the run ends well and
discarded otherwise, as Session does with a derived output.  `parts()` gives the
checked parts themselves to a command that consumes them as they come (check,
report).
"""

from __future__ import annotations

import os

from sniffer.capture.session import Session, close_source, storage_text
from sniffer.events import CaptureError
from sniffer.formats.mcap.sink import CaptureStorageError
from sniffer.parallel.engine import Engine


class ParallelRun:
    """See the module doc; `engine` after run() says how it went (parts redone, a tail run in order)."""

    keep_partial = False

    def __init__(self, spec, source, outputs=(), *, jobs: int, on_event=None, label: str = "") -> None:
        self.spec, self.source = spec, source
        self.plans = [plan for plan, _ in outputs]
        self.writers = [writer for _, writer in outputs]
        self.jobs = jobs
        self.on_event = on_event
        self.label = label
        self.session = Session(spec, source, [])
        self.info = self.resolved = self.engine = None
        self.frames_out = self.bytes_in = self.noise_bytes = 0
        self.error: str | None = None
        self.storage_error = False
        self.interrupted = False

    @property
    def damage(self) -> list[str]:
        return self.session.damage

    @property
    def notes(self) -> list[str]:
        return self.session.notes

    @property
    def outputs(self) -> list:
        return [o for w in self.writers for o in getattr(w, "outputs", ())]

    @property
    def registry(self):
        return self.session.registry

    @property
    def pipeline(self):
        """The coordinator's pipeline: never fed, its registries follow the parts taken (their naming)."""
        return self.session.pipeline

    def open(self):
        """Open the source and resolve the settings (Session.open), then the writers' files: a file that cannot
        be made fails now, in one line (CaptureError), with nothing left behind."""
        if self.info is None:
            info = self.session.open()
            try:
                for w in self.writers:
                    w.begin(info)
            except (CaptureStorageError, OSError) as e:
                self._abandon()
                raise CaptureError(storage_text(e, self.outputs)) from None
            except BaseException:
                self._abandon()
                raise
            self.info, self.resolved = info, self.session.resolved
        return self.info

    def _abandon(self) -> None:
        for w in self.writers:
            try:
                w.close()
            except Exception:  # noqa: BLE001 - already failing: the first error is the one to report
                pass
        for o in self.outputs:
            o.discard()
        self.session.close()

    def parts(self, plans=None):
        """The checked parts in order (sniffer.parallel.engine.Part), counted into the run's totals."""
        self.open()
        self.engine = Engine(self.spec, self.session, plans if plans is not None else self.plans, self.jobs)
        self.engine.on_event = self.on_event
        try:
            for part in self.engine.parts():
                c = part.counted
                self.frames_out += c.frames
                self.bytes_in += c.bytes_in
                self.noise_bytes += c.noise_bytes
                if c.error:
                    self.error = c.error
                yield part
        except KeyboardInterrupt:
            self.interrupted = True
            raise
        finally:
            self._close_source()

    def run(self) -> ParallelRun:
        completed = False
        try:
            try:
                self.open()
                for part in self.parts():
                    for w, piece in zip(self.writers, part.pieces):
                        w.add(piece)
                completed = True
            except BrokenPipeError:
                raise
            except (CaptureStorageError, OSError) as e:  # an output cannot be written (disk full, I/O error)
                self.storage_error = True
                self.error = self.error or f"{storage_text(e, self.outputs)} (stopped there)"
        finally:
            self._end(completed)
        return self

    def _end(self, completed: bool) -> None:
        first = None
        for w in self.writers:
            try:
                w.close()
            except (CaptureStorageError, OSError) as e:
                first = first or e
        if first is not None and not self.storage_error:
            self.storage_error = True
            self.error = self.error or storage_text(first, self.outputs)
        unexpected = not completed and not self.interrupted and self.error is None
        for o in self.outputs:
            if self.storage_error or unexpected:
                o.discard()
            else:
                o.commit()

    def _close_source(self) -> None:
        close_source(self.source)


def decode_capture(path, spec, jobs: int) -> ParallelRun:
    """An opened ParallelRun over a capture file (as sniffer.capture.session.decode_capture): its `parts(plans)`
    give the pieces in order."""
    from sniffer.capture.settings import CaptureSpec
    from sniffer.sources.segset import capture_source

    spec = spec or CaptureSpec()
    whole = spec.inputs if spec.inputs and spec.input == os.fspath(path) else os.fspath(path)  # check's set
    run = ParallelRun(spec, capture_source(whole, spec.input_format, spec.logic), jobs=jobs)
    run.open()
    return run
