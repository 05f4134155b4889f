"""A line read through pyserial alone, read-only: behind an RS-485-to-Ethernet gateway (`rfc2217://HOST:PORT`,
`socket://HOST:PORT`), or a COM port on Windows.

pyserial does the talking (serial.serial_for_url), so nothing here needs termios, fcntl or a
pseudo-terminal: this is the live path where those do not exist.  (On Linux and macOS a local port is
opened by serial_port.py instead: O_RDONLY, which pyserial cannot do; Windows has no read-only open of a
COM port, so there pyserial opens it, DTR and RTS off, and nothing is ever written.)
Read-only means no data byte is ever sent:

* socket:// (a device server's "TCP server" / raw mode): a plain TCP connection; we only receive;
* rfc2217:// (Telnet COM-PORT-OPTION): pyserial's client negotiates the Telnet options and then sets the
  gateway's port to the line (baud, data bits, parity, stop bits, no flow control), DTR and RTS off
  (a gateway that switches its transmitter by RTS stays receiving) and purges the gateway's receive
  buffer.  Those are commands to the gateway, never bytes on the bus (docs/gateways.md).

Timestamps are taken when a read returns, as for a USB adapter, but after the gateway's own buffering
(its packing timeout, often 1-50 ms) and the network: the capture's time source is "net".  A request and
its answer often arrive in one TCP segment, so the latency is missing more often than on a local adapter,
and silences shorter than the gateway's packing timeout cannot be seen.

The server going away (a restarted gateway, a cable pulled) is a Gap: the reader connects again with a
backoff (RECONNECT_FIRST_S doubling to RECONNECT_MAX_S), and the Gap's reason says it.
"""

from __future__ import annotations

import re

import os
import threading
import time
from collections.abc import Iterator

from sniffer.events import CaptureError, CaptureInfo, Chunk, Gap, Tick
from sniffer.line import LineSettings
from sniffer.sources.hub import Hub, PortLostError, ReaderEnd

SCHEMES = ("rfc2217://", "socket://")
READ_SIZE = 4096
RECONNECT_FIRST_S = 0.2
RECONNECT_MAX_S = 5.0
CONNECT_TIMEOUT_S = 5.0


def reads_through_pyserial(port: str) -> bool:
    """`port` is opened by pyserial here: a gateway's URL anywhere; any port on Windows (no termios)."""
    return is_url(port) or os.name == "nt"


def is_url(port: str) -> bool:
    """`port` names a line behind a gateway (a URL pyserial opens), not a local serial device."""
    return port.lower().startswith(SCHEMES)


class PyserialLine:
    """A line pyserial reads as a live source: `open()` (CaptureInfo), `events()`, `stop()` from any thread.

    The same face as serial_live.SerialSource (`port`, `lost_since_ns`, `lost_reason`, `losses`), so the
    capture's status and notices treat both alike."""

    def __init__(self, url: str, line: LineSettings, *, tick_interval_s: float = 0.005, reconnect: bool = True,
                 hub: Hub | None = None, link: str = "", channel: str = "", **_local_only) -> None:
        self.port = url
        self.line = line
        self.tick_ns = max(1, int(tick_interval_s * 1e9))
        self.reconnect = reconnect
        self.hub = hub or Hub()
        self.link = link
        self.channel = channel
        self.info: CaptureInfo | None = None
        self.lost_since_ns: int | None = None
        self.lost_reason = ""
        self.losses = 0
        self.reconnects = 0
        self._conn = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._ended = False

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        self._conn = self._connect()
        net = is_url(self.port)
        self.info = CaptureInfo(
            source=f"{'net' if net else 'serial'}:{self.port}", port=self.port, baud=self.line.baud,
            parity=self.line.parity, stopbits=self.line.stopbits, databits=self.line.databits,
            time_source="net" if net else "read", t0_ns=time.monotonic_ns(), wall_anchor_ns=time.time_ns(),
        )
        if net:
            self.info.extra["gateway"] = {"url": self.port, "scheme": self.port.split(":", 1)[0].lower()}
        else:
            self.info.extra["reader"] = {"via": "pyserial"}
        self._thread = threading.Thread(target=self._run, name=f"net-reader {self.port}", daemon=True)
        self._thread.start()
        return self.info

    def events(self) -> Iterator[Chunk | Tick | Gap]:
        self.open()
        if not self._ended:
            self._ended = True
            yield from self.hub.events(1)

    def stop(self) -> None:
        self._stop.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=5)

    def __enter__(self) -> "PyserialLine":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- connecting ----------------------------------------------------------------

    def _connect(self):
        """The open pyserial object for the URL, set to the line; CaptureError("<url>: <why>") otherwise."""
        import serial

        try:
            conn = serial.serial_for_url(self.port, do_not_open=True)
        except (serial.SerialException, ValueError) as e:
            raise CaptureError(f"{self.port}: {_text(e)}") from None
        conn.baudrate = self.line.baud
        conn.bytesize = self.line.databits
        conn.parity = self.line.parity
        conn.stopbits = self.line.stopbits
        conn.timeout = self.tick_ns / 1e9
        # before open: RFC 2217 sends them once, in its negotiation (see the module doc); socket:// ignores them
        conn.dtr = False
        conn.rts = False
        try:
            conn.open()
        except (serial.SerialException, OSError, ValueError) as e:
            raise CaptureError(f"{self.port}: {_text(e)}") from None
        return conn

    # -- reader thread -------------------------------------------------------------

    def _run(self) -> None:
        import serial

        push, clock, link, channel = self.hub.push, self.hub.clock, self.link, self.channel
        try:
            last = time.monotonic_ns()
            while not self._stop.is_set():
                if self._conn is None:
                    self._wait_for_server()
                    last = time.monotonic_ns()
                    continue
                try:
                    data = self._read(self._conn)
                except (serial.SerialException, OSError) as e:
                    self._lose(_text(e))
                    continue
                with clock:
                    now = time.monotonic_ns()  # right after the read: the read's (network) time
                    if data:
                        push(Chunk(now, data, None, (), channel, link))
                        last = now
                    elif now - last >= self.tick_ns:
                        push(Tick(now, link))
                        last = now
        except BaseException as e:  # handed to the consumer, raised from events()
            self._error = e
        finally:
            self._close()
            self.hub.push(ReaderEnd(self))

    def _read(self, conn) -> bytes:
        """What arrived: waits up to a tick for the first byte, then takes what is already there."""
        first = conn.read(1)
        if not first:
            return b""
        waiting = conn.in_waiting
        if not waiting:
            return first
        if _is_socket(conn):  # its in_waiting only says "some": one non-blocking read takes them all
            conn.timeout = 0
            try:
                return first + conn.read(READ_SIZE)
            finally:
                conn.timeout = self.tick_ns / 1e9
        return first + conn.read(waiting)  # rfc2217: its reader thread's queue, counted exactly

    def _lose(self, reason: str) -> None:
        self._close()
        if not self.reconnect:
            raise PortLostError(f"{self.port}: connection lost ({reason})")
        self.lost_since_ns = time.monotonic_ns()
        self.lost_reason = reason
        self.losses += 1
        self.hub.lost(self)

    def _wait_for_server(self) -> None:
        """Connect again with a growing backoff; one Gap covers the whole outage."""
        lost, reason = self.lost_since_ns, self.lost_reason
        wait = RECONNECT_FIRST_S
        while not self._stop.wait(wait):
            try:
                conn = self._connect()
            except CaptureError:
                wait = min(wait * 2, RECONNECT_MAX_S)
                continue
            back = time.monotonic_ns()
            self._conn = conn
            self.reconnects += 1
            self.lost_since_ns = None
            self.hub.lost(self)
            with self.hub.clock:
                self.hub.push(Gap(lost, back, f"{self._what} lost ({reason}), reconnected", self.link))
            return
        with self.hub.clock:
            self.hub.push(Gap(lost, time.monotonic_ns(),
                              f"{self._what} lost ({reason}), capture stopped before it returned", self.link))

    @property
    def _what(self) -> str:
        return "gateway connection" if is_url(self.port) else "port"

    def _close(self) -> None:
        conn, self._conn = self._conn, None
        if conn is not None:
            try:
                conn.close()
            except Exception:  # noqa: BLE001 - a connection already gone may fail to close; it is gone either way
                pass


def _is_socket(conn) -> bool:
    from serial.urlhandler import protocol_socket

    return isinstance(conn, protocol_socket.Serial)


def _text(e: BaseException) -> str:
    text = str(e) or type(e).__name__
    # pyserial says "Could not open port socket://h:p: [Errno 111] Connection refused"; the URL is said already
    if text.lower().startswith("could not open port ") and ": " in text[20:]:
        text = text[20:].split(": ", 1)[1]
    # "[Errno 111] Connection refused" -> what it means for a gateway
    m = re.match(r"\[Errno (-?\d+)\] (.*)", text)
    if m:
        errno_, why = int(m.group(1)), m.group(2)
        hint = _HINTS.get(errno_)
        text = f"{why[:1].lower()}{why[1:]}" + (f" ({hint})" if hint else "")
    return text


_HINTS = {  # what the engineer checks, by errno (connect to a device server)
    111: "nothing listens there: is the device server on, in TCP server mode, at that port?",
    113: "no route to the device server: its address, the network cable, the subnet",
    110: "the device server does not answer: its address, a firewall",
    -2: "the host name is not known: check it, or give the device server's IP address",
    -3: "the host name could not be looked up now: check the DNS, or give the IP address",
}
