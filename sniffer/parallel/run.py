"""A capture decoded by parts in worker processes, with what a capture session gives its command.

    run = ParallelRun(spec, source, sinks, jobs=4)     # made by sniffer.decoding.decode(..., jobs=4)
    run.open()                      # the source opened and the settings resolved, as Session.open
    run.run()                       # the parts decoded, their pieces written in order
    for f in run: ...               # or every frame, in order, here (as from a Session)
    for piece in run.pieces(plan):  # or a plan's pieces, in order (check's golden lines)
    report(run, label=...)          # frames_out, bytes_in, error, damage, notes, outputs: as a Session's

Each sink is split into a plan (the workers' half) and a writer (this process's)
by what it says of itself (`split`, sniffer.parallel.outputs.SPLITS); a sink that
does not split runs here, fed the parts' frames and raw events in one process's
order (CallsPlan, SinkWriter).  A writer takes a plan's pieces in capture order;
its `outputs` (files under temporary names) are committed when the run ends well
and discarded otherwise, as Session does with a derived output.
"""

from __future__ import annotations

from sniffer.capture.session import Session, close_source, storage_text
from sniffer.events import CaptureError
from sniffer.formats.mcap.sink import CaptureStorageError
from sniffer.parallel.engine import Engine
from sniffer.parallel.outputs import FramesPlan, split


class ParallelRun:
    """See the module doc; `engine` after run() says how it went (parts redone, a tail run in order)."""

    keep_partial = False

    def __init__(self, spec, source, sinks=(), *, jobs: int, on_event=None, label: str = "") -> None:
        self.spec, self.source = spec, source
        self.sinks = list(sinks)
        self.plans: list = []
        self.writers: list = []
        self.jobs = jobs
        self.on_event = on_event
        self.label = label
        self.hooks: list = []  # told `opened(self)` and `ended(self)`, as a Session's
        self.session = Session(spec, source, [])
        self.info = self.resolved = self.engine = None
        self.frames_out = self.bytes_in = self.noise_bytes = 0
        self.error: str | None = None
        self.storage_error = False
        self.interrupted = False
        self.ended = False
        for s in self.sinks:
            plan, writer = split(s)
            self.plans.append(plan)
            self.writers.append(writer)

    @property
    def damage(self) -> list[str]:
        return self.session.damage

    @property
    def notes(self) -> list[str]:
        return self.session.notes

    @property
    def outputs(self) -> list:
        return [o for w in self.writers for o in w.outputs]

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
            try:
                info = self.session.open()
            except BaseException:
                self.ended = True
                for h in self.hooks:
                    h.ended(self)
                raise
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
            for h in self.hooks:
                h.opened(self)
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
        self.ended = True
        for h in self.hooks:
            h.ended(self)

    def _parts(self, plans):
        """The checked parts in order (sniffer.parallel.engine.Part), counted into the run's totals."""
        self.engine = Engine(self.spec, self.session, plans, self.jobs)
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
            close_source(self.source)

    def pieces(self, plan=None):
        """Each part's piece of `plan`, in capture order, the sinks' pieces written on the way (None: only those;
        nothing is yielded)."""
        plans = [*self.plans, plan] if plan is not None else self.plans
        completed = False
        try:
            try:
                self.open()
                for part in self._parts(plans):
                    for w, piece in zip(self.writers, part.pieces):
                        w.add(piece)
                    if plan is not None:
                        yield part.pieces[-1]
                completed = True
            except BrokenPipeError:
                raise
            except (CaptureStorageError, OSError) as e:  # an output cannot be written (disk full, I/O error)
                self.storage_error = True
                self.error = self.error or f"{storage_text(e, self.outputs)} (stopped there)"
        finally:
            self._end(completed)

    def __iter__(self):
        """Every frame, in order, here (as a Session gives them); the sinks written on the way."""
        for frames in self.pieces(FramesPlan()):
            yield from frames

    def run(self) -> ParallelRun:
        for _ in self.pieces():
            pass
        return self

    def close(self) -> None:
        """End a run that was opened but is not run to its end (its outputs are discarded)."""
        if not self.ended:
            if self.info is None:
                self._abandon()
            else:
                close_source(self.source)
                self._end(completed=False)

    def _end(self, completed: bool) -> None:
        if self.ended:
            return
        self.ended = True
        try:
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
        finally:
            for h in self.hooks:
                h.ended(self)
