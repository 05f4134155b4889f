"""`sniffer serve`: the TUI in browsers (textual-serve); the capture runs as a process of its own."""

from __future__ import annotations

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import UsageError
from sniffer.commands.flags import (
    backlog_flag, capture_out_flags, command_parser, decode_flags, foxglove_flags, mqtt_flags, number, port_flags,
    scenario_flags, serial_flags, trigger_flags, unattended_flags,
)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "serve", help="serve the TUI to browsers (textual-serve); the capture runs on its own",
        description="""\
            Capture a port (or the demo bus) and serve its TUI to web browsers: each browser gets a viewer of
            its own, none can write to the port.  Terminal users `sniffer attach` the same capture.  Ctrl-C
            stops serving, then the capture (its MCAP is closed and kept).""",
        examples=["sniffer serve /dev/ttyUSB0 --bus line.toml --out cab3.mcap",
                  "sniffer serve --demo --host 0.0.0.0 --http-port 8080",
                  "sniffer attach /run/user/1000/sniffer-4242.sock    # the same capture, in a terminal"])
    port_flags(p, " (or --demo)")
    p.add_argument("--demo", action="store_true", help="capture the simulated bus of `sniffer demo` instead")
    scenario_flags(p, seed=False, what=" (with --demo)")
    serial_flags(p, "live")
    decode_flags(p, "live")
    capture_out_flags(p, None, 0, named="sniffer-<time>.mcap; with --demo: demo.mcap")
    g = p.add_argument_group("serving")
    g.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only)")
    g.add_argument("--http-port", type=number(int, "--http-port", 1, 65535), default=8000, help="HTTP port")
    g.add_argument("--public-url", help="URL browsers use to reach the server (when behind a proxy or --host 0.0.0.0)")
    g.add_argument("--socket", metavar="PATH",
                   help="where the capture publishes (default: a fresh one in $XDG_RUNTIME_DIR or /tmp)")
    backlog_flag(g)
    unattended_flags(p, port=True)
    trigger_flags(p)
    foxglove_flags(p)
    mqtt_flags(p)


def run(spec: CaptureSpec, args) -> int:
    from sniffer import need

    need("web", "sniffer serve")
    from sniffer.processes.serve import ServeUsageError, run_serve

    if args.demo:
        given = [flag for flag, v in (("PORT", spec.port), ("--baud", spec.flags.baud), ("--parity", spec.flags.parity),
                                      ("--stopbits", spec.flags.stopbits), ("--bus", spec.bus_file)) if v]
        if given:
            raise UsageError(f"--demo sets its own line; {', '.join(given)} is for a serial PORT")
        spec = spec.with_(scenario=args.scenario, out=None if args.no_out else (spec.out or "demo.mcap"))
    elif not spec.port:
        raise UsageError("give a serial PORT to capture, or --demo")
    try:
        return run_serve(spec, args)
    except ServeUsageError as e:
        raise UsageError(str(e)) from None
