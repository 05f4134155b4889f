"""`sniffer serve`: the TUI in a browser (textual-serve), any number of viewers.

textual-serve starts one app process per browser connection, so the capture
cannot live in the UI: `serve` starts it as a process of its own (processes/capture.py)
(`sniffer live PORT ... --publish SOCKET` or `sniffer demo ... --publish
SOCKET`, its CaptureSpec on stdin), waits until it publishes, then serves `sniffer attach SOCKET --tui`
to browsers.  Terminal users attach to the same socket.  Ctrl-C stops the
web server, then the capture (which closes its MCAP file).
"""

from __future__ import annotations

import asyncio
import os
import shlex
import signal
import socket
import sys
import tempfile
import threading

from sniffer.processes.capture import CaptureProcess


class ServeUsageError(Exception):
    pass


def default_socket() -> str:
    where = os.environ.get("XDG_RUNTIME_DIR") or tempfile.gettempdir()
    return os.path.join(where, f"sniffer-{os.getpid()}.sock")


def viewer_command(sock: str) -> str:
    """The shell command textual-serve runs for each browser connection: `exec`, so the viewer is the
    process the server stops (not a shell in front of it), and it ends with the server (processes/parent_death.py)."""
    return f"exec {shlex.quote(sys.executable)} -m sniffer attach {shlex.quote(sock)} --tui --exit-with-parent"


def _check_http_port(host: str, port: int) -> None:
    """Fail before the capture starts if the web server could not listen."""
    try:
        addrs = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as e:
        raise ServeUsageError(f"--host {host}: {e.strerror}") from None
    for family, kind, proto, _, addr in addrs:
        with socket.socket(family, kind, proto) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind(addr)
            except OSError as e:
                raise ServeUsageError(f"{host}:{port}: {e.strerror} (choose another --http-port)") from None


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def _server_class():
    """textual-serve's Server, made to stop its viewers promptly and tidily.

    * On shutdown it asks every viewer app to quit: aiohttp waits for open
      websockets, and a browser tab left open would hold the exit back.
    * When a browser leaves, it waits for the viewer process to exit: textual-serve
      does not, and the garbage collector then closes the process's pipes after the
      event loop is gone, with 'Event loop is closed' tracebacks.
    """
    import textual_serve.server as ts
    from textual_serve.app_service import AppService

    running: set[AppService] = set()

    class ViewerProcess(AppService):
        async def start(self, width: int, height: int) -> None:
            running.add(self)
            await super().start(width, height)

        async def stop(self) -> None:
            running.discard(self)
            await super().stop()  # asks the app to quit
            process = getattr(self, "_process", None)
            if process is None:
                return
            if not process.stdin.is_closing():
                process.stdin.close()
            try:
                await asyncio.wait_for(process.wait(), 5)
            except TimeoutError:
                process.kill()
                await process.wait()

    class ViewerServer(ts.Server):
        async def on_shutdown(self, app) -> None:
            await asyncio.gather(*(v.stop() for v in list(running)), return_exceptions=True)

    ts.AppService = ViewerProcess  # the name Server.handle_websocket creates its app services with
    return ViewerServer


def run_serve(spec, args) -> int:
    try:
        from aiohttp.web_runner import GracefulExit

        Server = _server_class()
    except ImportError:
        raise ServeUsageError("sniffer serve needs textual-serve (pip install textual-serve)") from None
    sock = os.path.abspath(args.socket or default_socket())
    if not args.demo and not args.no_out and not spec.out:
        from sniffer.capture.summary import default_capture_name

        spec = spec.with_(out=default_capture_name())
    _check_http_port(args.host, args.http_port)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"sniffer: note: serving on {args.host}: anyone who reaches port {args.http_port} there sees the "
              f"bus traffic (the viewers cannot write to the port)", file=sys.stderr)
    signal.signal(signal.SIGTERM, _interrupt)  # as Ctrl-C until the web server takes the signals over
    capture = CaptureProcess(spec, "demo" if args.demo else "live", sock)
    child = capture.child
    stopping = threading.Event()
    try:
        if not capture.wait_publishing():
            return capture.rc()  # it said why on stderr

        def _watch():
            rc = child.wait()
            if not stopping.is_set():
                print(f"sniffer: the capture ended (exit {rc}); open views keep what they have, new ones cannot "
                      f"attach. Ctrl-C stops serving.", file=sys.stderr)

        threading.Thread(target=_watch, name="capture-watch", daemon=True).start()
        print(f"sniffer: viewers: http://{args.host}:{args.http_port} in a browser, "
              f"or 'sniffer attach {sock}' in a terminal", file=sys.stderr)
        server = Server(viewer_command(sock), host=args.host, port=args.http_port, title="rs485-sniffer",
                        public_url=args.public_url)
        try:
            server.serve()
        except GracefulExit:  # a second Ctrl-C while the server was stopping
            pass
    finally:
        stopping.set()
        rc = capture.stop()
    return rc if rc and rc > 0 else 0
