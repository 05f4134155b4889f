"""One capture session under every command: settings resolved once, one loop, one way to end.

    spec = CaptureSpec.from_args(args)                       # flags + bus file (cli.py)
    session = Session(spec, FileSource("line3.mcap"), [FileSink("csv", "line3.csv", inputs=["line3.mcap"])])
    result = session.run()                                   # or: for frame in session: ...

Settings.  A setting can come from four places; the first that says it wins:
flags > bus file > the capture's own metadata > defaults (`layered`).  Device
maps and per-unit timeouts merge unit by unit by the same rule.  `CaptureSpec`
holds the flags and the bus file (what the user said); `resolve(info)` adds
what the capture says and the defaults and checks the result (baud known, a
protocol we speak, models that speak it), giving `Resolved`: line settings,
protocol, device map, timeouts, and a fresh decoder registry.

The loop (`Session.frames`).  Open the source first (a missing port or an
unreadable file ends the command before any output exists), resolve, open the
sinks, then feed every event through one Pipeline.  A `stop` event (Ctrl-C,
SIGTERM, the TUI's quit, `--duration`) ends the source; a full disk ends the
capture with what was written intact; damage a file source skipped is listed
in `damage`.  At the end the pipeline's pending frames are flushed, the sinks
closed and their files renamed into place (sniffer.outputs): kept whatever
ended a capture (`keep_partial`, live/demo/simulate), discarded when a derived
output (an export) could not be written.

Every command goes through here: live, demo, replay, decode, simulate, export,
check, diff, serve's capture process and the TUI's feeds.
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace

from . import __version__, protocols
from .events import CaptureInfo
from .frame import Frame
from .line import LineSettings, SettingsError
from .pairer import DEFAULT_TIMEOUT_MS
from .pipeline import Pipeline
from .sinks import FileSink
from .sinks.mcap import CaptureStorageError
from .sources import CaptureError

MAX_TIMEOUT_MS = 86_400_000.0  # a day: anything longer is a typo, not a response timeout
MAX_DURATION_S = 366 * 86_400.0


def finite(value, what: str, *, upper: float) -> float:
    """A number that must be finite, >= 0 and <= upper (flags, bus files): SettingsError otherwise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{what} {str(value)[:60]!r} is not a number") from None
    if not math.isfinite(v) or v < 0 or v > upper:
        raise SettingsError(f"{what} {str(value)[:60]} must be a finite number from 0 to {upper:.0f}")
    return v


# ---------------------------------------------------------------- settings
@dataclass(frozen=True)
class LineChoice:
    """What one place says about the line (flags, a bus file, a capture, the defaults); None = nothing."""

    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    databits: int | None = None
    protocol: str | None = None
    devices: Mapping[int, str] = field(default_factory=dict)
    timeout_ms: float | None = None
    unit_timeouts: Mapping[int, float] = field(default_factory=dict)

    @classmethod
    def from_info(cls, info: CaptureInfo | None) -> LineChoice:
        if info is None:
            return cls()
        return cls(info.baud, info.parity, info.stopbits, info.databits, info.protocol, dict(info.devices or {}))

    @classmethod
    def from_bus(cls, bus) -> LineChoice:
        if bus is None:
            return cls()
        return cls(bus.baud, bus.parity, bus.stopbits, None, bus.protocol, dict(bus.devices),
                   None, dict(bus.timeouts_ms))


DEFAULTS = LineChoice(parity="N", stopbits=1, databits=8, protocol=protocols.DEFAULT, timeout_ms=DEFAULT_TIMEOUT_MS)


def layered(*layers: LineChoice) -> LineChoice:
    """The one precedence rule: the first layer that says a thing wins; maps merge unit by unit."""
    def first(name):
        return next((getattr(x, name) for x in layers if getattr(x, name) is not None), None)

    devices: dict[int, str] = {}
    timeouts: dict[int, float] = {}
    for x in reversed(layers):
        devices.update(x.devices)
        timeouts.update(x.unit_timeouts)
    return LineChoice(first("baud"), first("parity"), first("stopbits"), first("databits"), first("protocol"),
                      devices, first("timeout_ms"), timeouts)


@dataclass(frozen=True)
class Resolved:
    """The settings a capture runs with, checked."""

    line: LineSettings
    protocol: protocols.Protocol
    devices: dict[int, str]
    model_files: tuple[str, ...]
    timeout_ms: float
    unit_timeouts: dict[int, float]

    def registry(self):
        """A fresh decoder registry (decoders keep per-unit state: one per pipeline)."""
        from decoders.registry import default_registry

        return default_registry(self.devices, list(self.model_files) or None, default=self.protocol.default_model)

    def pipeline(self, info: CaptureInfo, sinks, registry=None) -> Pipeline:
        return Pipeline(info, self.line, registry or self.registry(), sinks, protocol=self.protocol.name,
                        timeout_ms=self.timeout_ms, unit_timeouts=self.unit_timeouts or None)

    def record_in(self, info: CaptureInfo) -> None:
        """The settings used travel with the capture (an MCAP written from it replays without flags)."""
        info.baud, info.parity, info.stopbits = self.line.baud, self.line.parity, self.line.stopbits
        info.databits = self.line.databits
        info.protocol = self.protocol.name
        info.devices = dict(self.devices)

    def describe(self) -> str:
        models = ", ".join(f"{u}={m}" for u, m in sorted(self.devices.items()))
        return f"{self.line.label()} {self.protocol.name}" + (f" ({models})" if models else "")


@dataclass(frozen=True)
class CaptureSpec:
    """What the user asked for, in one object: built once from the flags and the bus file.

    `flags` and `bus` are the two top layers of the precedence rule; the capture's
    metadata and DEFAULTS are added by `resolve`.  The rest says where the capture
    comes from (port, input file, simulated scenario) and where it goes.
    """

    flags: LineChoice = LineChoice()
    bus_file: str | None = None
    bus: LineChoice = LineChoice()
    model_files: tuple[str, ...] = ()
    # where the capture comes from
    port: str | None = None
    input: str | None = None
    input_format: str = "auto"
    scenario: str | None = None
    seed: int = 1
    duration_s: float = 0.0
    # where it goes
    out: str | None = None  # the MCAP file a live capture or demo writes (None: none)
    stream: str | None = "text"  # frames on stdout: "text", "jsonl" or None (quiet)
    headless: bool = False
    publish: str | None = None
    publish_backlog: int = 100_000

    @classmethod
    def of(cls, *, baud=None, parity=None, stopbits=None, protocol=None, devices=None, timeout_ms=None,
           unit_timeouts=None, model_files=(), bus_file: str | None = None, **kw) -> CaptureSpec:
        """A spec from keyword arguments (the pytest plugin, tests): they are the flags layer."""
        flags = LineChoice(baud, parity.upper() if parity else None, stopbits, None, protocol,
                           {int(u): str(m) for u, m in (devices or {}).items()}, timeout_ms,
                           dict(unit_timeouts or {}))
        return cls(flags=flags, bus_file=bus_file, bus=_load_bus(bus_file), model_files=tuple(model_files), **kw)

    @classmethod
    def from_args(cls, args) -> CaptureSpec:
        """The spec for parsed command-line flags (any subset: each command has the flags it needs)."""
        from decoders.registry import parse_device_args

        def opt(name, default=None):
            return getattr(args, name, default)

        timeout = opt("timeout_ms")
        flags = LineChoice(opt("baud"), opt("parity"), opt("stopbits"), None, opt("protocol"),
                           parse_device_args(opt("device")),
                           None if timeout is None else finite(timeout, "--timeout-ms", upper=MAX_TIMEOUT_MS))
        duration = opt("duration", 0.0) or 0.0
        fmt = opt("format", "text")
        return cls(
            flags=flags, bus_file=opt("bus"), bus=_load_bus(opt("bus")), model_files=tuple(opt("model_file") or ()),
            port=opt("port"), input=opt("file"), input_format=opt("input_format", "auto") or "auto",
            scenario=opt("scenario"), seed=opt("seed", 1) or 1,
            duration_s=finite(duration, "--duration", upper=MAX_DURATION_S),
            out=None if opt("no_out") else opt("out"),
            stream=None if opt("quiet") else (fmt if fmt in ("text", "jsonl") else "text"),
            headless=bool(opt("headless")), publish=opt("publish"),
            publish_backlog=opt("publish_backlog", 100_000),
        )

    def with_(self, **changes) -> CaptureSpec:
        return replace(self, **changes)

    def resolve(self, info: CaptureInfo | None = None, *, need_baud: bool = True) -> Resolved:
        """flags > bus file > `info` (the capture's metadata) > defaults, checked; SettingsError otherwise."""
        c = layered(self.flags, self.bus, LineChoice.from_info(info), DEFAULTS)
        where = f"{info.source or 'the capture'}" if info is not None else "the line"
        if c.baud is None:
            if need_baud:
                raise SettingsError(f"{where} does not say its baud rate: give --baud (and --parity/--stopbits)")
            c = replace(c, baud=9600)
        line = LineSettings(_int(c.baud, "baud rate"), str(c.parity).upper(), _int(c.stopbits, "stop bits"),
                            _int(c.databits, "data bits"))
        protocol = protocols.get(c.protocol)
        timeouts = {int(u): finite(ms, f"timeout of unit {u}", upper=MAX_TIMEOUT_MS)
                    for u, ms in c.unit_timeouts.items()}
        resolved = Resolved(line, protocol, dict(c.devices), self.model_files,
                            finite(c.timeout_ms, "response timeout", upper=MAX_TIMEOUT_MS), timeouts)
        registry = resolved.registry()  # unknown models and bad model files fail here, before anything opens
        for unit, model in sorted(resolved.devices.items()):
            fam = getattr(registry.decoders[model], "family", "pd" if model == "pd-series" else "modbus")
            if fam != protocol.family:
                speaks = ", ".join(n for n, p in protocols.PROTOCOLS.items() if p.family == fam)
                raise SettingsError(f"unit {unit}: model {model} speaks {speaks}, not {protocol.name} "
                                    f"(give --protocol, or another model)")
        return resolved

    def to_argv(self, command: str) -> list[str]:
        """The `sniffer live|demo ...` arguments that run this capture (serve starts it as a process)."""
        argv = [command]
        if command == "live":
            argv.append(self.port or "")
        f = self.flags
        for flag, value in (("--baud", f.baud), ("--parity", f.parity), ("--stopbits", f.stopbits),
                            ("--protocol", f.protocol), ("--timeout-ms", f.timeout_ms), ("--bus", self.bus_file)):
            if value is not None:
                argv += [flag, str(value)]
        for unit, model in sorted(f.devices.items()):
            argv += ["--device", f"{unit}={model}"]
        for path in self.model_files:
            argv += ["--model-file", path]
        if command == "demo":
            argv += ["--scenario", self.scenario or "default", "--seed", str(self.seed)]
        argv += ["--out", self.out] if self.out else ["--no-out"]
        argv += ["--duration", repr(self.duration_s)]
        if self.publish:
            argv += ["--publish", self.publish, "--publish-backlog", str(self.publish_backlog)]
        if self.headless:
            argv.append("--headless")
        if self.stream is None:
            argv.append("--quiet")
        elif self.stream == "jsonl":
            argv += ["--format", "jsonl"]
        return argv


def _int(v, what: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise SettingsError(f"{what} {str(v)[:60]!r} is not a whole number")
    try:
        return int(v)
    except ValueError:
        raise SettingsError(f"{what} {str(v)[:60]!r} is not a whole number") from None


def _load_bus(path: str | None) -> LineChoice:
    if not path:
        return LineChoice()
    from .busfile import load_bus_file

    return LineChoice.from_bus(load_bus_file(path))


# ---------------------------------------------------------------- the loop
class Session:
    """One capture: a source through one pipeline into sinks (see the module doc).

    `sinks` may hold FileSink plans (opened once the source is open) and sinks.
    After the run: `info`, `resolved`, `frames_out`, `bytes_in`, `noise_bytes`,
    `error` (why it ended early, or None), `storage_error` (an output could not be
    written), `damage` (input the source skipped), `interrupted` (Ctrl-C).
    """

    def __init__(self, spec: CaptureSpec, source, sinks: Iterable = (), *, stop: threading.Event | None = None,
                 keep_partial: bool = False, need_baud: bool = True, on_event=None) -> None:
        self.spec = spec
        self.source = source
        self.planned = list(sinks)
        self.stop = stop or threading.Event()
        self.keep_partial = keep_partial
        self.need_baud = need_baud
        self.on_event = on_event  # called with each source event (a progress bar)
        self.info: CaptureInfo | None = None
        self.resolved: Resolved | None = None
        self.registry = None
        self.pipeline: Pipeline | None = None
        self.sinks: list = []
        self.error: str | None = None
        self.storage_error = False
        self.interrupted = False
        self.ended = False
        self._started = False
        self._frames: Iterator[Frame] | None = None

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
    def outputs(self) -> list:
        return [o for s in self.planned for o in getattr(s, "outputs", ())]

    # ------------------------------------------------------------ running
    def open(self) -> CaptureInfo:
        """Open the source, resolve the settings, open the sinks and the pipeline; idempotent."""
        if self.info is not None:
            return self.info
        info = self.source.open()
        try:
            self.resolved = self.spec.resolve(info, need_baud=self.need_baud)
            self.resolved.record_in(info)
            info.sniffer_version = info.sniffer_version or __version__
            self.registry = self.resolved.registry()
            for s in self.planned:
                self.sinks.append(s.open() if isinstance(s, FileSink) else s)
            self.pipeline = self.resolved.pipeline(info, self.sinks, self.registry)
        except BaseException as e:
            self._abandon()
            if isinstance(e, (CaptureStorageError, OSError)):  # e.g. the disk is full already
                raise CaptureError(self._storage_text(e)) from None
            raise
        self.info = info
        return info

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
        flushers = [s.maybe_flush for s in self.sinks if hasattr(s, "maybe_flush")]
        watcher = self._watch()
        stop, on_event, feed = self.stop, self.on_event, p.feed
        completed = False
        try:
            try:
                for ev in self.source.events():
                    out = feed(ev)
                    for flush in flushers:
                        flush()
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
            yield from p.flush()
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

    def close(self) -> None:
        """End a session that was opened but is not run to its end (its outputs are discarded)."""
        if self.pipeline is not None and not self.ended:
            self._end(completed=False)
        elif self.pipeline is None:
            self._abandon()

    def _watch(self) -> threading.Thread | None:
        """A thread that stops the source on `stop` or at the end of --duration."""
        duration = self.spec.duration_s
        source_stop = getattr(self.source, "stop", None)
        if source_stop is None:
            return None
        deadline = time.monotonic() + duration if duration > 0 else None

        def watch():
            while not self.stop.wait(0.05):
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
            keep = self.keep_partial or not self.storage_error
            unexpected = not completed and not self.interrupted and self.error is None
            for o in self.outputs:
                if keep and not unexpected:
                    o.commit()
                else:
                    o.discard()

    def _storage_text(self, e: Exception) -> str:
        """One line for an output that cannot be written, naming the user's file (not its part file)."""
        if isinstance(e, CaptureStorageError) and self.keep_partial:
            text = str(e)  # a capture: what it kept is what matters
        else:
            reason = (e.strerror or str(e)) if isinstance(e, OSError) else (getattr(e, "reason", "") or str(e))
            where = ", ".join(o.path for o in self.outputs)
            if not where and isinstance(e, OSError) and isinstance(e.filename, str):
                where = e.filename
            text = f"{where or 'output'}: cannot write: {reason}"
        for o in self.outputs:
            text = text.replace(o.part, o.path)
        return text

    def _close_source(self) -> None:
        for name in ("stop", "close"):
            fn = getattr(self.source, name, None)
            if fn is not None:
                try:
                    fn()
                except Exception:  # noqa: BLE001 - closing: nothing left to save
                    pass


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
    """An opened session over a capture file: iterate it for its decoded frames, one at a time.

    `.info` is the capture's metadata with the settings used; CaptureError /
    SettingsError (one line) for unreadable input or impossible settings.
    """
    from .sources.replay import FileSource

    spec = spec or CaptureSpec()
    session = Session(spec, FileSource(os.fspath(path), spec.input_format), sinks, on_event=on_event)
    session.open()
    return session


def on_signals(stop: threading.Event) -> None:
    """SIGINT and SIGTERM end the capture through `stop` (the sinks close, the files are kept)."""
    def handler(signum, frame):
        stop.set()

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
