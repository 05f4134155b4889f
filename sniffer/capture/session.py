"""One capture session under every command: settings resolved once, one loop, one way to end.

    spec = CaptureSpec.from_args(args)                       # flags + bus file (cli.py)
    session = Session(spec, FileSource("line3.mcap"), [FileSink("csv", "line3.csv", inputs=["line3.mcap"])])
    result = session.run()                                   # or: for frame in session: ...

Settings (sniffer.capture.settings, re-exported here).  One precedence rule: flags >
bus file > the capture's own metadata > defaults.  `CaptureSpec` holds what
the user said; `resolve(info)` gives `Resolved`, what the capture runs with.

The loop (`Session.frames`).  Open the source first (a missing port or an
unreadable file ends the command before any output exists), resolve, open the
sinks, then feed every event through one Pipeline.  A `stop` event (Ctrl-C,
SIGTERM, the TUI's quit, `--duration`) ends the source; a full disk ends the
capture with what was written intact; damage a file source skipped is listed
in `damage`.  At the end the pipeline's pending frames are flushed, the sinks
closed and their files renamed into place (sniffer.formats.outputs): kept whatever
ended a capture (`keep_partial`, live/demo/simulate), discarded when a derived
output (an export) could not be written.

Unattended capture (sniffer.formats.mcap.segments).  With `--rotate` the MCAP is a set of
segments (formats/mcap/rotating.py): between two events, once one is due and the
pipeline has settled (`Pipeline.settled`), the loop closes the segment and
opens the next, so each replays alone.  With a status file (`--status`, or
the folder of a rotated capture) a StatusSink (sniffer.capture.status) counts frames
and errors and merges every sink's `status()` into the file.

Every command goes through here: live, demo, replay, decode, simulate, export,
check, diff, serve's capture process and the TUI's feeds.  A capture of
several links (its CaptureInfo lists `links`) runs one pipeline per link, their
frames merged in time order for the same sinks (sniffer.capture.links.LinkPipelines);
`resolved` and `registry` are then its first link's, `pipeline.resolved` /
`.registries` every link's.
Sinks the spec asks for are added here, so every command has them: the
trigger sink (--trigger, sniffer.triggers) and the MQTT sink (--mqtt,
sniffer.mqtt).
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING

from sniffer import __version__
from sniffer.events import CaptureInfo, Gap
from sniffer.frame import Frame
from sniffer.capture.pipeline import Pipeline
from sniffer.capture.settings import (  # noqa: F401 - re-exported: the session's settings
    DEFAULTS, MAX_DURATION_S, MAX_TIMEOUT_MS, CaptureSpec, LineChoice, Resolved, finite, layered,
)
from sniffer.formats.mcap.segments import STATUS_NAME, folder_for

if TYPE_CHECKING:
    from sniffer.capture.links import LinkPipelines
from sniffer.formats import FileSink
from sniffer.formats.mcap.sink import CaptureStorageError
from sniffer.formats.mcap.rotating import SegmentPlan
from sniffer.sinks.base import Sink, overrides
from sniffer.events import CaptureError


class Session:
    """One capture: a source through one pipeline into sinks (see the module doc).

    `sinks` may hold FileSink plans (opened once the source is open) and sinks.
    After the run: `info`, `resolved`, `frames_out`, `bytes_in`, `noise_bytes`,
    `error` (why it ended early, or None), `storage_error` (an output could not be
    written), `damage` (input the source skipped), `interrupted` (Ctrl-C).
    """

    def __init__(self, spec: CaptureSpec, source, sinks: Iterable = (), *, stop: threading.Event | None = None,
                 keep_partial: bool = False, need_baud: bool = True, on_event=None, label: str = "") -> None:
        self.spec = spec
        self.source = source
        self.planned = list(sinks)
        self.stop = stop or threading.Event()
        self.keep_partial = keep_partial
        self.need_baud = need_baud
        self.on_event = on_event  # called with each source event (a progress bar)
        self.hooks: list = []  # told `opened(self)` and `ended(self)` (sniffer.decoding: the bar, the notes)
        self.label = label or spec.port or spec.input or spec.scenario or ""  # what the status file says it is
        self.info: CaptureInfo | None = None
        self.resolved: Resolved | None = None
        self.registry = None
        self.pipeline: Pipeline | LinkPipelines | None = None
        self.sinks: list = []
        self.error: str | None = None
        self.storage_error = False
        self.interrupted = False
        self.ended = False
        self._started = False
        self._frames: Iterator[Frame] | None = None
        from sniffer.capture.status import check_status

        check_status(spec)  # a status file that cannot be written: one line, before anything opens
        if spec.trigger is not None:
            from sniffer.triggers import windows_place

            windows_place(spec)  # a folder that cannot take the windows: one line, before anything opens

    # ------------------------------------------------------------ results
    @property
    def frames_out(self) -> int:
        return self.pipeline.frames_out if self.pipeline else 0

    @property
    def bytes_in(self) -> int:
        return self.pipeline.bytes_in if self.pipeline else 0

    @property
    def noise_bytes(self) -> int:
        return self.pipeline.noise_bytes if self.pipeline else 0

    @property
    def damage(self) -> list[str]:
        return list(getattr(self.source, "damage", None) or ())

    @property
    def notes(self) -> list[str]:
        """What the source skipped that is not damage (a segment that held nothing)."""
        return list(getattr(self.source, "notes", None) or ())

    @property
    def outputs(self) -> list:
        return [o for s in self.planned if isinstance(s, (Sink, FileSink, SegmentPlan)) for o in s.outputs]

    # ------------------------------------------------------------ running
    def open(self) -> CaptureInfo:
        """Open the source, resolve the settings, open the sinks and the pipeline; idempotent."""
        if self.info is not None:
            return self.info
        info = self.source.open()
        try:
            info.sniffer_version = info.sniffer_version or __version__
            links = None
            if info.links:  # several links: one pipeline each (sniffer.capture.links), each link's settings checked now
                links = {str(x.get("name", "")): self.spec.resolve_link(str(x.get("name", "")), info,
                                                                        need_baud=self.need_baud)
                         for x in info.links}
                self.resolved = next(iter(links.values()))
            else:
                self.resolved = self.spec.resolve(info, need_baud=self.need_baud)
                self.resolved.record_in(info)
            # the station that captured it (Foxglove's deviceName: formats/mcap/foxglove.py): kept by a replay or export
            info.extra["device_name"] = (self.spec.foxglove_device or info.extra.get("device_name")
                                         or socket.gethostname())
            from decoders.carry import of_info, record

            self.registry = self.resolved.registry(of_info(info))
            if not links:  # what the capture starts with, in its metadata (LinkPipelines records every link's)
                record(info, {"": self.registry.carried()})
            for s in self.planned:
                self.sinks.append(s.open() if isinstance(s, (FileSink, SegmentPlan)) else s)
            triggers = None
            if self.spec.trigger is not None:
                from sniffer.triggers import trigger_sink

                # several links: the link that waits longest for an answer decides how long a window waits
                slowest = max(links.values(), key=lambda r: max([r.timeout_ms, *r.unit_timeouts.values()])) \
                    if links else self.resolved
                triggers = trigger_sink(self.spec, slowest, self.registry)
                self.sinks.append(triggers)
            mqtt = None
            if self.spec.mqtt is not None:
                from sniffer.mqtt.sink import mqtt_sink

                mqtt = mqtt_sink(self.spec, self.registry)
                self.sinks.append(mqtt)
            status = self.status_path()
            if status:
                from sniffer.capture.status import StatusSink

                self.sinks.append(StatusSink(status, self, self.label))
            if links:
                from sniffer.capture.links import LinkPipelines

                self.pipeline = LinkPipelines(info, links, self.sinks)
                self.registry = next(iter(self.pipeline.registries.values()))
                if mqtt is not None:  # model names from every link's models
                    mqtt.registries = list(self.pipeline.registries.values())
            else:
                self.pipeline = self.resolved.pipeline(info, self.sinks, self.registry)
            if triggers is not None:
                triggers.settled = self.pipeline.settled
            for s in self.sinks:  # parts cut later (segments, windows, dataset files) start with what it knows then
                if overrides(s, "bind"):
                    s.bind(self.pipeline)
        except BaseException as e:
            self._abandon()
            if isinstance(e, (CaptureStorageError, OSError)):  # e.g. the disk is full already
                raise CaptureError(self._storage_text(e)) from None
            raise
        self.info = info
        for h in self.hooks:
            h.opened(self)
        return info

    def status_path(self) -> str | None:
        """The status file: --status, or status.json in a rotated capture's folder (None: no status file)."""
        spec = self.spec
        if spec.status:
            return spec.status
        if spec.rotate is not None and spec.out:
            return os.path.join(folder_for(spec.out), STATUS_NAME)
        return None

    def _abandon(self) -> None:
        """open() failed: close what was opened, remove every part file."""
        for s in self.sinks:
            try:
                s.close()
            except Exception:  # noqa: BLE001 - already failing; the first error is the one to report
                pass
        for o in self.outputs:
            o.discard()
        self._close_source()
        for h in self.hooks:
            h.ended(self)

    def __iter__(self) -> Iterator[Frame]:
        """The session's one stream of frames (iterating again continues it)."""
        if self._frames is None:
            self._frames = self.frames()
        return self._frames

    def frames(self) -> Iterator[Frame]:
        """Every settled, decoded frame, in order, as the sinks get them (flat memory); one pass."""
        if self._started:
            raise RuntimeError("a session runs once")
        self._started = True
        self.open()
        p = self.pipeline
        flushers = [s.maybe_flush for s in self.sinks if overrides(s, "maybe_flush")]
        rotators = [s for s in self.sinks if overrides(s, "rotate_if")]  # segments close between events
        clocks = [s.advance for s in self.sinks if overrides(s, "advance")]  # capture time, every event
        watcher = self._watch()
        stop, on_event, feed = self.stop, self.on_event, p.feed
        completed = False
        try:
            try:
                for ev in self.source.events():
                    out = feed(ev)
                    for flush in flushers:
                        flush()
                    for r in rotators:
                        if r.rotate_due:
                            r.rotate_if(p.settled())
                    for clock in clocks:
                        clock(ev.t_end_ns if type(ev) is Gap else ev.t_ns)
                    if on_event is not None:
                        on_event(ev)
                    if out:
                        yield from out
                    if stop.is_set():
                        break
            except BrokenPipeError:
                raise  # stdout piped into `head`: the command ends quietly (cli.main)
            except (CaptureStorageError, OSError) as e:  # an output cannot be written (disk full, I/O error)
                self.storage_error = True
                self.error = f"{self._storage_text(e)} (stopped there)"
            except CaptureError as e:
                self.error = str(e)
            try:
                yield from p.flush()
            except BrokenPipeError:
                raise
            except (CaptureStorageError, OSError) as e:  # the last frames could not be written
                self.storage_error = True
                self.error = self.error or f"{self._storage_text(e)} (stopped there)"
            completed = True
        except (KeyboardInterrupt, BrokenPipeError):
            self.interrupted = True  # the user's doing: what was written is kept
            raise
        finally:
            self.stop.set()
            if watcher is not None:
                watcher.join(1)
            self._end(completed)

    def run(self) -> Session:
        """Drive the whole source; returns self (see the class doc for the results)."""
        for _ in self:
            pass
        return self

    def pieces(self, plan, batch: int = 1024) -> Iterator:
        """A part plan's pieces (sniffer.parallel.outputs) of the frames, in order, `batch` frames a piece: what
        a run by parts gives, from this one process (a command reads either the same way)."""
        sink, n, first = None, 0, True
        for f in self:
            if sink is None:
                sink = plan.part_sink(self.info, first)
                sink.start(self.info)
                first = False
            sink.frame(f)
            n += 1
            if n >= batch:
                sink.close()
                yield sink.piece()
                sink, n = None, 0
        if sink is not None:
            sink.close()
            yield sink.piece()

    def close(self) -> None:
        """End a session that was opened but is not run to its end (its outputs are discarded)."""
        if self.pipeline is not None and not self.ended:
            self._end(completed=False)
        elif self.pipeline is None:
            self._abandon()

    def _watch(self) -> threading.Thread | None:
        """A thread that stops the source on `stop` or at the end of --duration, and says on stderr when a
        live source's port goes away and comes back (status.PortNotices)."""
        duration = self.spec.duration_s
        source_stop = getattr(self.source, "stop", None)
        if source_stop is None:
            return None
        deadline = time.monotonic() + duration if duration > 0 else None
        from sniffer.capture.status import PortNotices, port_readers

        notices = PortNotices(self.source) if port_readers(self.source) else None

        def watch():
            while not self.stop.wait(0.05):
                if notices is not None:
                    notices.check()
                if deadline is not None and time.monotonic() >= deadline:
                    break
            source_stop()

        t = threading.Thread(target=watch, name="session-stop", daemon=True)
        t.start()
        return t

    def _end(self, completed: bool) -> None:
        if self.ended:
            return
        p = self.pipeline
        try:
            if not completed:  # interrupted: what is pending still reaches the sinks
                try:
                    p.flush()
                except Exception:  # noqa: BLE001 - the interruption is what gets reported
                    pass
            try:
                p.close()
            except BrokenPipeError:
                raise
            except (CaptureStorageError, OSError) as e:
                self.storage_error = True
                self.error = self.error or self._storage_text(e)
        finally:
            self._close_source()
            self.ended = True
            try:
                self._outputs_end(completed)
            finally:
                for h in self.hooks:
                    h.ended(self)

    def _outputs_end(self, completed: bool) -> None:
        """The outputs renamed into place, kept as parts, or discarded (see the module doc)."""
        unexpected = not completed and not self.interrupted and self.error is None
        kept = []
        for o in self.outputs:
            if self.storage_error and self.keep_partial:  # cut short: never under the name asked for
                if o.keep_part():
                    kept.append(o.part)
            elif self.storage_error or unexpected:
                o.discard()
            else:
                o.commit()
        kept += [p for s in self.sinks if isinstance(s, Sink) for p in s.kept_parts]  # e.g. a segment cut short
        if kept:
            how = ": `sniffer replay` reads it, `sniffer repair` finishes it" \
                if all(".mcap" in p for p in kept) else ""
            self.error = f"{self.error or 'cannot write'}; what was written is kept as {', '.join(kept)} " \
                         f"(not complete{how})"

    def _storage_text(self, e: Exception) -> str:
        return storage_text(e, self.outputs, self.keep_partial)

    def _close_source(self) -> None:
        close_source(self.source)


def close_source(source) -> None:
    """Stop and close a capture's source, whatever either raises (closing: nothing left to save)."""
    for name in ("stop", "close"):
        fn = getattr(source, name, None)
        if fn is not None:
            try:
                fn()
            except Exception:  # noqa: BLE001 - closing: nothing left to save
                pass


def storage_text(e: Exception, outputs, keep_partial: bool = False) -> str:
    """One line for an output that cannot be written, naming the user's file (not its part file)."""
    if isinstance(e, CaptureStorageError) and (keep_partial or not outputs):
        text = str(e)  # a capture (or its segments): what it kept is what matters
    else:
        reason = (e.strerror or str(e)) if isinstance(e, OSError) else (getattr(e, "reason", "") or str(e))
        where = ", ".join(o.path for o in outputs)
        if not where and isinstance(e, OSError) and isinstance(e.filename, str):
            where = e.filename
        text = f"{where or 'output'}: cannot write: {reason}"
    for o in outputs:
        text = text.replace(o.part, o.path)
    return text


class EventSource:
    """Events already at hand (a benchmark's chunks, a test's bursts) as a session source."""

    def __init__(self, info: CaptureInfo, events: Iterable) -> None:
        self.info = info
        self._events = events
        self._stop = False

    def open(self) -> CaptureInfo:
        return self.info

    def events(self):
        for ev in self._events:
            if self._stop:
                return
            yield ev

    def stop(self) -> None:
        self._stop = True


def run(spec: CaptureSpec, source, sinks: Iterable = (), **kw) -> Session:
    """Session(spec, source, sinks, **kw).run()."""
    return Session(spec, source, sinks, **kw).run()


def decode_capture(path: str | os.PathLike[str], spec: CaptureSpec | None = None, sinks: Iterable = (),
                   *, on_event=None) -> Session:
    """An opened session over a capture file: iterate it for its decoded frames, one at a time (one process;
    the commands take sniffer.decoding.decode_file, which decodes by parts too).

    `.info` is the capture's metadata with the settings used; CaptureError /
    SettingsError (one line) for unreadable input or impossible settings.
    """
    from sniffer.sources.segset import capture_source

    spec = spec or CaptureSpec()
    whole = spec.inputs if spec.inputs and spec.input == os.fspath(path) else os.fspath(path)  # check's set
    session = Session(spec, capture_source(whole, spec.input_format, spec.logic), sinks, on_event=on_event)
    session.open()
    return session


def on_signals(stop: threading.Event) -> None:
    """SIGINT and SIGTERM end the capture through `stop` (the sinks close, the files are kept)."""
    def handler(signum, frame):
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
