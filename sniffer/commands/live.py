"""`sniffer live PORT...`: capture a line (read-only) and decode it live, into MCAP (commands/capture.py runs it).

Several ports (or a --tap pair, or a bus file's [[links]]) are several links on one
timeline; `sigrok:DRIVER` is a logic analyzer read by sigrok-cli.
"""

from __future__ import annotations

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.capture import run_capture
from sniffer.commands.common import UsageError, default_capture_name, need_posix_tty, tui_wanted
from sniffer.commands.flags import (
    capture_out_flags, child_flag, command_parser, decode_flags, foxglove_flags, headless_flag, logic_flags,
    mqtt_flags, port_flags, publish_flags, serial_flags, stream_flags, trigger_flags, unattended_flags,
)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "live",
        help="capture a serial port (read-only) and decode live; several ports: several links on one timeline; "
             "sigrok:DRIVER: a logic analyzer",
        description="""\
            Capture a serial line and decode it as it comes: the TUI on a terminal, frame lines otherwise
            (--headless), and an MCAP file of everything (bytes, frames, settings) that `sniffer replay` reads
            again.  The port is opened read-only: nothing is ever sent on the bus.

            Settings come from the flags, then the --bus file, then the defaults; `sniffer detect PORT
            --write-bus line.toml` writes a bus file for a line whose settings you do not know.""",
        examples=["sniffer live /dev/ttyUSB0 --baud 19200 --parity E --out cabinet3.mcap",
                  "sniffer live /dev/ttyUSB0 --bus line.toml --wait-port --headless --quiet --rotate 1h "
                  "--keep 14d --out /var/lib/sniffer/cab3",
                  "sniffer live --bus plant.toml --out plant.mcap        # the [[links]] of a bus file",
                  "sniffer live socket://10.0.0.7:4001 --baud 19200 --parity E   # behind a gateway (rfc2217:// too)"])
    port_flags(p)
    p.add_argument("--only-link", action="append", metavar="NAME",
                   help="capture only this [[links]] table of the --bus file, with its settings (repeatable; "
                        "default: all of its links)")
    serial_flags(p, "live")
    logic_flags(p, live=True)
    decode_flags(p, "live")
    stream_flags(p, quiet="the MCAP file, --publish and --mqtt only")
    capture_out_flags(p, None, 0)
    headless_flag(p)
    publish_flags(p)
    unattended_flags(p, port=True)
    trigger_flags(p)
    foxglove_flags(p)
    mqtt_flags(p)
    child_flag(p)


def run(spec: CaptureSpec, args) -> int:
    from sniffer.sources.logic_options import is_device
    from sniffer.sources.pyserial_line import reads_through_pyserial

    if not spec.port:
        raise UsageError("live: give a PORT (several for several links), --tap PORT_A PORT_B, "
                         "or a --bus file with [[links]]")
    if any(is_device(p) for plan in spec.links for p in plan.ports):
        raise UsageError("a logic analyzer (sigrok:DRIVER) is one capture of its own: give it alone")
    if is_device(spec.port) or spec.logic is not None:
        return _live_logic(spec)
    if any(reads_through_pyserial(p) for plan in spec.links for p in plan.ports) or reads_through_pyserial(spec.port):
        return _live_pyserial(spec, args)
    need_posix_tty("live (reading a serial port)")
    from sniffer.processes.reader import live_source

    if not args.no_out and not spec.out and not args.spec_from_stdin:  # the capture process's spec is settled
        name = default_capture_name()
        spec = spec.with_(out=name[:-5] if spec.rotate is not None else name)
    if spec.links:  # several links, or a tapped one: each resolved now, before a port opens
        plans = [(plan, spec.resolve_link(plan.name, need_baud=False).line) for plan in spec.links]
        label = " ".join(plan.name for plan in spec.links)
        ports = [p for plan in spec.links for p in plan.ports]
        if tui_wanted(spec):
            from sniffer.tui.run import run_capture_tui

            return run_capture_tui(spec, "live", label)
        return run_capture(spec, live_source("links", plans), label, inputs=ports,
                           what=lambda: f"capturing {len(plans)} links: " + "; ".join(
                               f"{p.name} ({' + '.join(p.ports)}{', tapped' if p.tap else ''})" for p, _ in plans))
    line = spec.resolve(None, need_baud=False).line  # flags > bus file > defaults: the port's settings
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "live", spec.port)
    source = live_source("serial", spec.port, line)
    return run_capture(spec, source, spec.port, inputs=[spec.port], status_label=f"live {spec.port}")


def _live_pyserial(spec: CaptureSpec, args) -> int:
    """`live rfc2217://HOST:PORT` or `socket://HOST:PORT` (a line behind a gateway), or a COM port on Windows: read
    by pyserial alone, in this process (sources/pyserial_line.py: no termios, no reader process)."""
    from sniffer.sources.pyserial_line import PyserialLine, is_url

    if spec.links:
        raise UsageError("a gateway's line (rfc2217:// or socket://) or a port read by pyserial is one capture of "
                         "its own: give it alone")
    if not args.no_out and not spec.out and not args.spec_from_stdin:
        name = default_capture_name()
        spec = spec.with_(out=name[:-5] if spec.rotate is not None else name)
    line = spec.resolve(None, need_baud=False).line
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "live", spec.port)
    source = PyserialLine(spec.port, line)
    return run_capture(spec, source, spec.port, status_label=f"live {spec.port}",
                       what=lambda: f"capturing {spec.port}" + (" through its gateway (network read times)"
                                                                 if is_url(spec.port) else ""))


def _live_logic(spec: CaptureSpec) -> int:
    """`live sigrok:DRIVER --rx CH ...`: a logic analyzer read continuously by sigrok-cli (sources/sigrok_cli.py)."""
    from sniffer.sources.logic_options import DeviceSpec, is_device
    from sniffer.sources.sigrok_cli import device_source

    if not is_device(spec.port):
        raise UsageError(f"--rx/--tx/--de are for a logic analyzer: give sigrok:DRIVER (e.g. sigrok:fx2lafw), "
                         f"not {spec.port}")
    if spec.logic is None:
        raise UsageError(f"{spec.port}: say which channel carries the line: --rx CHANNEL (and --baud)")
    device = DeviceSpec.parse(spec.port)
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "live", spec.port)
    source = device_source(device, spec.logic)  # no sigrok-cli, no such driver or channel: one line, nothing made
    wires = ", ".join(f"{k} {v}" for k, v in spec.logic.to_dict().items() if v)
    what = f"capturing {device} at {source.rate_label}: {wires}"
    return run_capture(spec, source, str(device), what=lambda: what, status_label=f"live {device}")
