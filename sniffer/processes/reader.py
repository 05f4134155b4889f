"""A live capture's port readers in a process of their own: a read's time never waits for the capture's interpreter.

Why: a reader thread takes a read's time once it holds the interpreter again.  In the capture's
process the decoding thread holds it most of the time, and when that thread loses its CPU while
holding it (preempted by anything else on a loaded machine: a TUI, a kworker, the publisher), the
reader waits until it runs again.  A read that comes that late holds a request and its answer
together, and the answer has no latency (a TUI open beside the capture makes such preemptions
several times more frequent: benchmarks/HISTORY.md).
Here the readers (serial_live.SerialSource, several of them for serial_links.LinksSource) share an
interpreter with nothing but each other: the process's main thread only waits for its pipe to end.

    parent (the capture)                      child: python -m sniffer.processes.reader EV CTL
    ReaderProcess.open()  -- (kind, args, kw) on CTL -->  builds the source on a PipeHub, opens it
                          <-- ("info", CaptureInfo) or ("error", exception) on EV
    events(): EV's messages as events     <--  each reader pushes its events (pipe_message) on EV
    ReaderProcess.stop(): CTL closed      -->  the source stopped; every reader's end on EV; exit

The child ignores SIGINT, SIGTERM and SIGHUP (ending a capture is its parent's: it ends once CTL
closes, which a parent killed with SIGKILL closes too).  A child that dies ends the capture's
readers with one error line ("the port's reader process ended ..."); what was captured is kept.
It opens the port as the reader thread did: read-only, nothing ever written.

SNIFFER_READER=thread keeps the readers threads of the capture's own process (the peer of
benchmarks/bench_capture_timing.py, and a way out where a helper process cannot start).
"""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator

from sniffer.processes.pipes import child_env, pipe_message, pipe_size, read_messages, write_all
from sniffer.events import CaptureInfo, Chunk, Gap, Tick, read_fields
from sniffer.events import CaptureError
from sniffer.sources.hub import Hub, ReaderEnd

READER_ENV = "SNIFFER_READER"  # "thread": readers in the capture's own process
PIPE_BYTES = 1 << 20  # the events the capture may be behind before a reader waits for it
START_S = 30.0  # the child's imports and the port's opening, on a loaded machine
STOP_S = 10.0


def live_source(kind: str, *args, **kw):
    """The live source `kind` ("serial": SerialSource(port, line, **kw); "links": LinksSource(plans, **kw)),
    its readers in a process of their own (ReaderProcess), or threads of this one if SNIFFER_READER=thread."""
    if os.environ.get(READER_ENV, "").strip().lower() == "thread":
        return _make(kind, args, kw)
    return ReaderProcess(kind, *args, **kw)


def _make(kind: str, args: tuple, kw: dict):
    if kind == "serial":
        from sniffer.sources.serial_live import SerialSource

        return SerialSource(*args, **kw)
    if kind == "links":
        from sniffer.sources.serial_links import LinksSource

        return LinksSource(*args, **kw)
    raise ValueError(f"unknown live source {kind!r}")


class _Port:
    """A port as the capture's status sees it (status.py): whether it is away now, since when, why, and how
    often it went."""

    __slots__ = ("losses", "lost_reason", "lost_since_ns", "port")

    def __init__(self, port: str) -> None:
        self.port = port
        self.lost_since_ns: int | None = None
        self.lost_reason = ""
        self.losses = 0  # times it went away (status.PortNotices)


class ReaderProcess:
    """A live source read by a process of its own: `open()` (CaptureInfo), `events()`, `stop()` from any
    thread; `readers` for the status (which port is away)."""

    def __init__(self, kind: str, *args, **kw) -> None:
        self.kind, self.args, self.kw = kind, args, kw
        if kind == "links":
            ports = [p for plan, _line in args[0] for p in plan.ports]
        else:
            ports = [args[0]]
        self.readers = [_Port(p) for p in ports]
        self.info: CaptureInfo | None = None
        self._proc: subprocess.Popen | None = None
        self._ctl: int | None = None  # the child's control pipe (closed: stop)
        self._ev: int | None = None  # the child's events' pipe
        self._messages: Iterator[tuple] | None = None
        self._lock = threading.Lock()
        self._reading = False  # events() began: it closes the events' pipe, not stop()

    @property
    def port(self) -> str:
        return " ".join(r.port for r in self.readers)

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        ev_r = self._spawn()
        self._ev, self._messages = ev_r, read_messages(ev_r)
        first, hung = self._opening(self._messages)
        if first is None or first[0] != "info":
            self.stop()
            if hung:
                raise CaptureError(f"{self.port}: the port's reader process did not open the port within "
                                   f"{START_S:.0f} s")
            if first is None:
                raise CaptureError(f"{self.port}: the port's reader process ended before the port opened "
                                   f"({_exit_text(self._proc.returncode)})")
            raise first[1]  # the port's own error (CaptureError: one line), as the reader thread raised it
        self.info = first[1]
        return self.info

    def _spawn(self) -> int:
        """Start the child with its two pipes; the read end of its events' pipe."""
        ev_r, ev_w = os.pipe()
        ctl_r, ctl_w = os.pipe()
        pipe_size(ev_w, PIPE_BYTES)
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "sniffer.processes.reader", str(ev_w), str(ctl_r)],
                pass_fds=(ev_w, ctl_r), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, env=child_env())
        except OSError as e:
            for fd in (ev_r, ctl_w):
                os.close(fd)
            raise CaptureError(f"{self.port}: cannot start the port's reader process: {e.strerror or e}") from None
        finally:
            os.close(ev_w)
            os.close(ctl_r)
        self._ctl = ctl_w
        return ev_r

    def _opening(self, messages: Iterator[tuple]) -> tuple[tuple | None, bool]:
        """Send the child its source and wait for the ports' opening: ("info", CaptureInfo) or ("error", e), or
        None if the child ended first; and whether it was killed for hanging (START_S)."""
        hung: list[bool] = []

        def kill_hung() -> None:
            hung.append(True)
            self._proc.kill()

        slow = threading.Timer(START_S, kill_hung)
        slow.start()
        try:
            write_all(self._ctl, pipe_message((self.kind, self.args, self.kw)))
            # skipped: what the readers of ports already open said before one that could not open stopped them
            for msg in messages:
                if msg[0] in ("info", "error"):
                    return msg, False
            return None, bool(hung)
        except BrokenPipeError:
            return None, bool(hung)
        finally:
            slow.cancel()

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        """Every port's events in time order, until every reader ended (stop(), or the child's end); a reader's
        error is raised as its reader thread's was (serial_live.Hub.events)."""
        self.open()
        with self._lock:
            if self._reading or self._ev is None:
                return
            self._reading = True
        try:
            yield from self._events_from(self._messages)
        finally:
            os.close(self._ev)

    def _events_from(self, messages: Iterator[tuple]) -> Iterator[Chunk | Tick | Gap]:
        ports = {r.port: r for r in self.readers}
        ended: set[str] = set()
        try:
            for msg in messages:
                tag = msg[0]
                if tag == "c":
                    yield Chunk(*msg[1])
                elif tag == "t":
                    yield Tick(msg[1], msg[2])
                elif tag == "g":
                    yield Gap(*msg[1:])
                elif tag == "l":
                    r = ports[msg[1]]
                    r.lost_since_ns, r.lost_reason = msg[2], msg[3]
                    r.losses += msg[2] is not None
                elif tag == "e":
                    if msg[2] is not None:
                        raise msg[2]
                    ended.add(msg[1])
        except (pickle.UnpicklingError, EOFError, IndexError, KeyError, TypeError, ValueError) as e:
            raise CaptureError(f"{self.port}: the port's reader process sent what cannot be read "
                               f"({type(e).__name__}: {e})") from None
        if len(ended) < len(self.readers):
            proc = self._proc
            code = proc.wait() if proc is not None else None
            raise CaptureError(f"{self.port}: the port's reader process ended ({_exit_text(code)}); "
                               "the capture stopped there")

    def stop(self) -> None:
        with self._lock:
            ctl, self._ctl = self._ctl, None
            ev = None
            if not self._reading:  # nobody reads the events: closed here (the child, writing, ends)
                ev, self._ev, self._reading = self._ev, None, True
        for fd in (ctl, ev):
            if fd is not None:
                os.close(fd)  # ctl: the child stops its readers, sends their ends, exits
        proc = self._proc
        if proc is not None:
            try:
                proc.wait(STOP_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

    def __enter__(self) -> "ReaderProcess":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def _exit_text(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


# -- the child -------------------------------------------------------------------------


class PipeHub(Hub):
    """The child's Hub: every event goes straight to the capture's pipe, in the order the readers push
    them (they push under `clock`; the pipe's own lock keeps a message whole)."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self.fd = fd
        self.gone = False  # the capture closed its end: nobody is left to tell anything
        self._write = threading.Lock()

    def send(self, msg: tuple) -> None:
        data = pipe_message(msg)
        with self._write:
            if not self.gone:
                try:
                    write_all(self.fd, data)
                except BrokenPipeError:
                    self.gone = True

    def push(self, item) -> None:
        t = type(item)
        if t is Chunk:
            self.send(("c", read_fields(item)))
        elif t is Tick:
            self.send(("t", item.t_ns, item.link))
        elif t is Gap:
            self.send(("g", item.t_ns, item.t_end_ns, item.reason, item.link))
        elif t is ReaderEnd:
            self.send(("e", item.source.port, _picklable(item.source._error)))

    def lost(self, reader) -> None:
        self.send(("l", reader.port, reader.lost_since_ns, reader.lost_reason))


def _picklable(error: BaseException | None) -> BaseException | None:
    """The error as it crosses the pipe: itself if it pickles back, else a CaptureError saying it."""
    if error is None:
        return None
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001
        return CaptureError(f"{type(error).__name__}: {error}")


def main(argv: list[str]) -> int:
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    ev, ctl = int(argv[0]), int(argv[1])
    hub = PipeHub(ev)
    messages = read_messages(ctl)
    spec = next(messages, None)
    if spec is None:
        return 0
    kind, args, kw = spec
    source = _make(kind, args, {**kw, "hub": hub})
    try:
        info = source.open()
    except BaseException as e:  # noqa: BLE001 - handed to the capture, which says it in one line
        hub.send(("error", _picklable(e)))
        return 0
    try:
        hub.send(("info", info))
        for _ in messages:  # nothing more is sent: this waits for the capture to close the pipe
            pass
    finally:
        source.stop()  # every reader's end, on the pipe
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except Exception as e:  # noqa: BLE001 - one line; the capture says the reader process ended
        print(f"sniffer: the port's reader process: {type(e).__name__}: {e}", file=sys.stderr)
        sys.exit(1)
