"""The capture's status file: what an engineer logged in remotely asks first, rewritten every few seconds.

    {"format": "sniffer.status/1", "state": "running", "pid": 4242, "command": "live /dev/ttyUSB0",
     "line": "19200 8E1 modbus-rtu", "started": "2026-11-25T10:41:00Z", "updated": "...", "uptime_s": 3600.2,
     "frames": 81234, "bytes": 1620000, "capture_s": 3599.99,
     "errors": {"crc": 2, "exceptions": 1, "timeouts": 4, "retries": 0, "faults": 0, "alarms": 0, "noise": 0,
                "uart": 0, "gaps": 1},
     "units": {"1": {"requests": 40210, "responses": 40205, "timeouts": 4, ..., "lat_median": 4.77}, ...},
     "last_frame": {"t": 3599.98, "wall": "2026-11-25T11:40:59Z"},
     "port": {"state": "ok"},
     "segments": {...}}                  <- a sink's status() (formats/mcap/rotating.py), merged in

`StatusSink` is a sink like the others (it counts the frames it is given);
the session adds it when the capture has a status file (`--status FILE`, or
`status.json` in the folder of a --rotate capture).  Any other sink with a
`status()` method contributes its dict (one top-level key of its own, e.g.
`{"triggers": {...}}`); `sniffer status` shows sections it does not know
generically.  `units` is every unit's figures (sniffer.analysis.unitfigures, as
every view counts them), and `errors` adds them up, with what names no
unit (noise, UART errors, gaps).  The file is written atomically (a
temporary file renamed over it) from the capture loop every STATUS_EVERY_S,
and by a watchdog thread when the loop is waiting (a lost adapter: `port` then says since when), and
once more at the end (`state` "ended", with why).
"""

from __future__ import annotations

import os
import sys
import threading
import time

from decoders.registry import code_book
from sniffer import codes
from sniffer.events import Gap
from sniffer.formats.outputs import OutputError, check_output, write_json_atomic
from sniffer.sinks.base import Sink, overrides
from sniffer.stderr import say
from sniffer.analysis.unitfigures import UnitBook

STATUS_FORMAT = "sniffer.status/1"
STATUS_EVERY_S = 2.0
_NS = 1_000_000_000
_UART = code_book().in_category(codes.UART_CAT)
# the status file's error counts that are the units' figures added up (sniffer.analysis.unitfigures), by name
_FROM_UNITS = {"crc": "crc_errors", "exceptions": "exceptions", "timeouts": "timeouts", "retries": "retries",
               "faults": "faults", "alarms": "alarms"}


def iso(wall_ns: int | None) -> str | None:
    """UTC ISO 8601 of Unix-epoch ns, to the second (None for None)."""
    if wall_ns is None:
        return None
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(wall_ns // _NS))


class StatusSink(Sink):
    """Counts what the status file says and writes it (see the module doc).

    `session` gives the other sinks (their `status()`), the source (a lost port)
    and the settings; `label` is what the capture is ("live /dev/ttyUSB0")."""

    def __init__(self, path: str, session, label: str = "", *, every_s: float = STATUS_EVERY_S,
                 announce=None) -> None:
        self.path = path
        self.session = session
        self.label = label
        self.every_ns = int(every_s * _NS)
        self.announce = announce or say
        self.frames = 0
        self.units = UnitBook()
        self.errors = dict.fromkeys(("noise", "uart", "gaps"), 0)  # what names no unit (the rest: `units`)
        self.last_frame_t: int | None = None
        self.last_event_t: int | None = None  # capture time covered: what rates are per (a replay's is not the clock's)
        self.info = None
        self.started_mono = time.monotonic_ns()
        self.started_wall = time.time_ns()
        self._written = 0
        self._snapshot: dict = {}
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._watchdog: threading.Thread | None = None
        self.write_error: str | None = None

    # ------------------------------------------------------------ the sink
    def start(self, info) -> None:
        self.info = info
        self.refresh()
        self._watchdog = threading.Thread(target=self._watch, name="status-file", daemon=True)
        self._watchdog.start()

    def raw(self, event) -> None:
        if type(event) is Gap:
            self.errors["gaps"] += 1
            self.last_event_t = event.t_end_ns
        else:
            self.last_event_t = event.t_ns

    def frame(self, f) -> None:
        self.frames += 1
        self.last_frame_t = f.t_ns
        self.units.frame(f)
        e = self.errors
        if f.protocol == "noise":
            e["noise"] += 1
        for a in f.annotations:
            if a.code in _UART:
                e["uart"] += 1

    def error_counts(self) -> dict:
        """crc, exceptions, timeouts, retries, faults, alarms: every unit's figures added up; noise (frames), uart
        (bytes with a framing or parity error), gaps (the capture interrupted)."""
        total = self.units.total()
        e = {name: getattr(total, fig) for name, fig in _FROM_UNITS.items()}
        e.update(self.errors)
        return e

    def maybe_flush(self) -> None:
        if time.monotonic_ns() - self._written >= self.every_ns:
            self.refresh()

    def close(self) -> None:
        self._done.set()
        if self._watchdog is not None:
            self._watchdog.join(2)
        s = self.session
        why = s.error or ("interrupted" if s.interrupted else "stopped, or the input ended")
        self.refresh(state="ended", ended=why)

    # ------------------------------------------------------------ the file
    def snapshot(self, state: str = "running", **more) -> dict:
        """The status as a dict (every sink's `status()` merged in)."""
        info, s = self.info, self.session
        now_mono = time.monotonic_ns()
        anchor = info.wall_anchor_ns if info is not None else 0
        d = {
            "format": STATUS_FORMAT, "state": state, "pid": os.getpid(), "command": self.label,
            "source": info.source if info is not None else "",
            "line": _line(s),
            "started": iso(self.started_wall), "updated": iso(time.time_ns()),
            "updated_ns": time.time_ns(), "every_s": self.every_ns / _NS,
            "uptime_s": round((now_mono - self.started_mono) / _NS, 1),
            "frames": self.frames, "bytes": s.bytes_in, "errors": self.error_counts(),
            "units": self.units.to_dict(),
        }
        if self.last_event_t is not None and info is not None:
            d["capture_s"] = round((self.last_event_t - info.t0_ns) / _NS, 3)
        if self.last_frame_t is not None and info is not None:
            t = self.last_frame_t
            d["last_frame"] = {"t": round((t - info.t0_ns) / _NS, 6), "wall": iso(anchor + t - info.t0_ns)
                               if anchor else None}
        d["port"] = self._port()
        d.update(more)
        for sink in s.sinks:
            if overrides(sink, "status") and sink is not self:
                try:
                    d.update(sink.status())
                except Exception as e:  # noqa: BLE001 - a section that fails must not stop the capture
                    d[type(sink).__name__] = {"error": str(e)[:200]}
        return d

    def refresh(self, state: str = "running", **more) -> None:
        """Build the status now and write it (from the capture loop)."""
        snap = self.snapshot(state, **more)
        with self._lock:
            self._snapshot = snap
            self._write(snap)

    def _lost(self) -> dict[str, dict]:
        """The source's ports that are away now (several links: each reader's), {port: {since, reason}}."""
        lost = {}
        mono_to_wall = time.time_ns() - time.monotonic_ns()
        for reader in port_readers(self.session.source):
            since = getattr(reader, "lost_since_ns", None)
            if since is not None:
                lost[str(getattr(reader, "port", "?"))] = {"since": iso(since + mono_to_wall),
                                                           "reason": getattr(reader, "lost_reason", "") or ""}
        return lost

    def _port(self, lost: dict | None = None) -> dict:
        lost = self._lost() if lost is None else lost
        if not lost:
            return {"state": "ok"}
        first = min(lost.values(), key=lambda x: x["since"] or "")
        return {"state": "lost", **first, "ports": sorted(lost)}

    def _write(self, snap: dict) -> None:
        self._written = time.monotonic_ns()
        try:
            write_json_atomic(self.path, snap)
            self.write_error = None
        except OSError as e:  # a full disk must not stop the capture: said once
            if self.write_error is None:
                self.announce(f"warning: {self.path}: cannot write the status ({e.strerror or e})")
            self.write_error = str(e)

    def _watch(self) -> None:
        """While the loop waits (no events: a lost adapter), keep the file fresh (PortNotices, run by every
        capture's session, says on stderr when a port goes and comes back)."""
        while not self._done.wait(min(1.0, self.every_ns / _NS)):
            lost = self._lost()
            if time.monotonic_ns() - self._written < 2 * self.every_ns and not lost:
                continue
            with self._lock:
                if self._done.is_set():
                    return
                snap = dict(self._snapshot)
                snap.update(port=self._port(lost), updated=iso(time.time_ns()), updated_ns=time.time_ns(),
                            uptime_s=round((time.monotonic_ns() - self.started_mono) / _NS, 1))
                self._write(snap)


def port_readers(source) -> list:
    """The readers of a live source whose ports may go away (SerialSource, each link's, or a reader process's
    ports): they have `port`, `lost_since_ns` (None while it is there), `lost_reason` and `losses`."""
    readers = getattr(source, "readers", None)
    if readers:
        return list(readers)
    return [source] if hasattr(source, "lost_since_ns") else []


class PortNotices:
    """Says on stderr when a port of the capture's source goes away and when it comes back: every live
    capture, with or without a status file.  `check()` is polled (Session's watcher thread): the readers
    only count their losses (`losses`), so an outage shorter than a poll is said too, and a reader never
    waits for stderr."""

    def __init__(self, source, announce=None) -> None:
        self.source = source
        self.announce = announce or say
        self._seen: dict[int, tuple[bool, int]] = {}  # id(reader) -> (away, losses) as last said

    def check(self) -> None:
        for reader in port_readers(self.source):
            port = getattr(reader, "port", "?")
            away = getattr(reader, "lost_since_ns", None) is not None
            losses = getattr(reader, "losses", 0)
            was_away, said = self._seen.get(id(reader), (False, 0))
            if losses > said and not was_away:  # gone since the last look (and maybe back already)
                why = getattr(reader, "lost_reason", "") or "?"
                self.announce(f"{port}: port lost ({why}); waiting for it to come back")
                was_away = True
            if was_away and not away:
                self.announce(f"{port}: port back; capturing again")
            self._seen[id(reader)] = (away, losses)


def check_status(spec) -> None:
    """OutputError unless --status names a file the capture may write (sniffer.formats.outputs.check_output): never
    one of its inputs, never its --out, never anything but a regular file."""
    if spec.status is not None:
        try:
            check_output(spec.status, inputs=spec.read_paths(), what="--status",
                         outputs=[spec.out] if spec.out else [])
        except OutputError as e:
            text = str(e)
            raise OutputError(text if text.startswith("--status") else f"--status {text}") from None


def wait_for_ports(ports: list[str], stop: threading.Event, status_path: str | None, label: str,
                   poll_s: float = 0.5) -> bool:
    """--wait-port: until every one of `ports` exists (True) or `stop` is set (False), saying once on
    stderr which is not there (and again for one missing later, when the one before came), and in the
    status file (`state` "waiting for port"; `port.path` the first missing, `port.missing` all).  A port
    that exists but cannot be opened is not waited for: opening it gives its error."""
    said: set[str] = set()
    since = time.time_ns()
    last = 0.0
    while missing := [p for p in ports if not os.path.exists(p)]:
        for port in missing:
            if port not in said:
                said.add(port)
                print(f"sniffer: {port}: not there (adapter unplugged?); waiting for it (--wait-port)",
                      file=sys.stderr, flush=True)
        if status_path and time.monotonic() - last >= STATUS_EVERY_S:
            last = time.monotonic()
            try:
                write_json_atomic(status_path, {
                    "format": STATUS_FORMAT, "state": "waiting for port", "pid": os.getpid(), "command": label,
                    "started": iso(since), "updated": iso(time.time_ns()), "updated_ns": time.time_ns(),
                    "every_s": STATUS_EVERY_S,
                    "port": {"state": "absent", "since": iso(since), "path": missing[0], "missing": missing}})
            except OSError:
                pass
        if stop.wait(poll_s):
            return False
    return True


def _line(session) -> str:
    """The line's settings; with several links each link's, by name ("drives: 19200 8E1 ...; pumps: ...")."""
    links = getattr(session.pipeline, "resolved", None)
    if isinstance(links, dict) and len(links) > 1:
        return "; ".join(f"{name}: {r.describe()}" for name, r in links.items())
    return session.resolved.describe() if session.resolved is not None else ""

