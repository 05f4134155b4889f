"""A local RS-485-to-Ethernet gateway for the tests: a simulated line's pty, read as a device server reads its
UART, relayed to every TCP client (a device server's "TCP server" / raw mode: what `socket://` reads).

    with SimulatedLine(tmp_path, "default") as line, Gateway(line.path, LineSettings(19200, "E", 1)) as gw:
        gw.url                      # socket://127.0.0.1:PORT
        gw.restart(pause_s=1.0)     # the server goes away (clients dropped, port closed) and comes back
        gw.from_clients             # bytes the clients sent: 0 for a passive sniffer

`rfc2217=True` speaks RFC 2217 with pyserial's own server side (serial.rfc2217.PortManager): the Telnet
option negotiation and the port settings the client sets are recorded (`settings`); any data byte a client
sends counts in `from_clients`.
"""

from __future__ import annotations

import os
import select
import socket
import threading
import time


class _Port:
    """What PortManager sets on the gateway's serial port (the settings a client asked for)."""

    def __init__(self) -> None:
        self.baudrate, self.bytesize, self.parity, self.stopbits = 9600, 8, "N", 1
        self.rtscts = self.xonxoff = self.dsrdtr = False
        self.rts = self.dtr = None
        self.break_condition = False
        self.cts = self.dsr = self.ri = self.cd = False
        self.name = "gateway"

    def reset_input_buffer(self) -> None:
        pass

    def reset_output_buffer(self) -> None:
        pass


class Gateway:
    def __init__(self, pty_path: str, line, *, rfc2217: bool = False) -> None:
        from sniffer.sources.serial_port import open_read_only

        self.fd, _, _ = open_read_only(pty_path, line)
        self.rfc2217 = rfc2217
        self.port_settings = _Port()
        self.from_clients = 0
        self.to_clients = 0
        self.connections = 0
        self._clients: list[tuple[socket.socket, object]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._listener = self._listen(0)
        self.port = self._listener.getsockname()[1]
        self._up = threading.Event()
        self._up.set()
        self._threads = [threading.Thread(target=self._relay, daemon=True),
                         threading.Thread(target=self._accept, daemon=True)]

    @property
    def url(self) -> str:
        return f"{'rfc2217' if self.rfc2217 else 'socket'}://127.0.0.1:{self.port}"

    def __enter__(self) -> "Gateway":
        for t in self._threads:
            t.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._drop()
        self._listener.close()
        for t in self._threads:
            t.join(5)
        os.close(self.fd)

    def restart(self, pause_s: float) -> None:
        """The server goes away for `pause_s` (its clients dropped, nothing listening), then listens again."""
        self._up.clear()
        listener, self._listener = self._listener, None
        listener.close()
        self._drop()
        time.sleep(pause_s)
        self._listener = self._listen(self.port)
        self._up.set()

    def _listen(self, port: int) -> socket.socket:
        s = socket.socket()
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))
        s.listen(4)
        s.settimeout(0.1)
        return s

    def _drop(self) -> None:
        with self._lock:
            clients, self._clients = self._clients, []
        for conn, _ in clients:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            conn.close()

    def _accept(self) -> None:
        while not self._stop.is_set():
            if not self._up.wait(0.1):
                continue
            listener = self._listener
            try:
                conn, _ = listener.accept()
            except (OSError, AttributeError):
                continue
            conn.setblocking(True)
            manager = None
            if self.rfc2217:
                from serial.rfc2217 import PortManager

                manager = PortManager(self.port_settings, _Sender(conn))
            with self._lock:
                self._clients.append((conn, manager))
                self.connections += 1
            threading.Thread(target=self._listen_to, args=(conn, manager), daemon=True).start()

    def _listen_to(self, conn: socket.socket, manager) -> None:
        """What a client sends: RFC 2217 commands go to PortManager; data bytes are counted (never expected)."""
        while not self._stop.is_set():
            try:
                data = conn.recv(4096)
            except OSError:
                return
            if not data:
                return
            if manager is None:
                self.from_clients += len(data)
                continue
            for chunk in manager.filter(data):  # what is left after the Telnet commands: bytes for the bus
                self.from_clients += len(chunk)

    def _relay(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.fd], [], [], 0.1)
            if not ready:
                continue
            try:
                data = os.read(self.fd, 4096)
            except BlockingIOError:
                continue
            except OSError:
                return
            with self._lock:
                clients = list(self._clients)
            for conn, manager in clients:
                out = b"".join(manager.escape(data)) if manager is not None else data
                try:
                    conn.sendall(out)
                    self.to_clients += len(data)
                except OSError:
                    pass


class _Sender:
    """PortManager's `connection`: where its answers go."""

    def __init__(self, conn: socket.socket) -> None:
        self.conn = conn

    def write(self, data: bytes) -> None:
        try:
            self.conn.sendall(data)
        except OSError:
            pass
