"""`sniffer serve`: the TUI in a browser (textual-serve), any number of viewers.

textual-serve starts one app process per browser connection, so the capture
cannot live in the UI: `serve` starts it as a process of its own
(`sniffer live PORT ... --publish SOCKET` or `sniffer demo ... --publish
SOCKET`), waits until it publishes, then serves `sniffer attach SOCKET --tui`
to browsers.  Terminal users attach to the same socket.  Ctrl-C stops the
web server, then the capture (which closes its MCAP file).
"""

from __future__ import annotations

import asyncio
import os
import shlex
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

WAIT_FOR_CAPTURE_S = 30.0


class ServeUsageError(Exception):
    pass


def default_socket() -> str:
    where = os.environ.get("XDG_RUNTIME_DIR") or tempfile.gettempdir()
    return os.path.join(where, f"sniffer-{os.getpid()}.sock")


def capture_argv(spec, command: str, sock: str) -> list[str]:
    """The command line of the capture process: the spec's own flags (CaptureSpec.to_argv), publishing on sock."""
    spec = spec.with_(publish=sock, headless=True, stream=None)
    return [sys.executable, "-m", "sniffer", *spec.to_argv(command)]


def viewer_command(sock: str) -> str:
    """The shell command textual-serve runs for each browser connection: `exec`, so the viewer is the
    process the server stops (not a shell in front of it), and it ends with the server (lifeline.py)."""
    return f"exec {shlex.quote(sys.executable)} -m sniffer attach {shlex.quote(sock)} --tui --exit-with-parent"


def _publishing(sock: str) -> bool:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        try:
            s.connect(sock)
        except OSError:
            return False
    return True


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


def _stop(child: subprocess.Popen, timeout_s: float = 15.0) -> int:
    """Ask the capture to stop as Ctrl-C would (it closes its MCAP), then wait for it."""
    if child.poll() is None:
        child.send_signal(signal.SIGINT)
        try:
            child.wait(timeout_s)
        except subprocess.TimeoutExpired:
            print("sniffer: the capture did not stop; killing it (its MCAP stays readable: sniffer repair)",
                  file=sys.stderr)
            child.kill()
            child.wait()
    return child.returncode


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
        from .commands.common import default_capture_name

        spec = spec.with_(out=default_capture_name())
    argv = capture_argv(spec, "demo" if args.demo else "live", sock)
    _check_http_port(args.host, args.http_port)
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"sniffer: note: serving on {args.host}: anyone who reaches port {args.http_port} there sees the "
              f"bus traffic (the viewers cannot write to the port)", file=sys.stderr)
    signal.signal(signal.SIGTERM, _interrupt)  # as Ctrl-C until the web server takes the signals over
    from .lifeline import die_with_parent

    # the capture ends (as on Ctrl-C: its MCAP closed) if this process is killed without stopping it
    child = subprocess.Popen(argv, stdin=subprocess.DEVNULL, preexec_fn=lambda: die_with_parent(signal.SIGINT))
    stopping = threading.Event()
    try:
        deadline = time.monotonic() + WAIT_FOR_CAPTURE_S
        while not _publishing(sock):
            if child.poll() is not None:
                return child.returncode or 1  # it said why on stderr
            if time.monotonic() > deadline:
                print(f"sniffer: error: the capture did not publish on {sock} within {WAIT_FOR_CAPTURE_S:.0f} s",
                      file=sys.stderr)
                return 1
            time.sleep(0.05)

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
        rc = _stop(child)
    return rc if rc and rc > 0 else 0
