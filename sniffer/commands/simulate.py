"""`sniffer simulate`: write a simulated capture to MCAP or a byte CSV, or serve the line on a pty.

The capture holds what a device would have recorded: per-byte times (a
logic analyzer, --adapter wire) or per-read chunks of a USB adapter
(--adapter usb, the default, with glued and split frames).  An MCAP also
holds the decoded frames, like a live capture does, and says the scenario's
protocol and drive models, so a replay decodes with them by default.  With
--receiver-baud/--receiver-parity/--receiver-stopbits the device was set to
other settings than the line's: the capture holds what its UART received
(simulator/uart.py), errors flagged.

--pty PATH serves the line on a pseudo-terminal linked at PATH until Ctrl-C or
SIGTERM (the link is removed): what a UART at the settings a program sets on
its end receives (simulator/uartpty.py), for `detect` and `live` without hardware.
"""

from __future__ import annotations

import os
import threading

from sniffer.line import LineSettings
from sniffer.capture.session import Session, on_signals
from sniffer.capture.settings import CaptureSpec
from sniffer.formats import FileSink
from sniffer.commands.common import UsageError, need_posix_tty, report, say
from sniffer.commands.flags import (
    MAX_BAUD, capture_duration_flag, command_parser, fault_flag, foxglove_flags, number, scenario_flags, serial_flags,
    unattended_flags,
)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "simulate", help="write a simulated capture (MCAP or byte CSV by extension), or serve a "
                                     "simulated line on a pseudo-terminal (--pty)",
        description="""\
            Write what a sniffer on a simulated bus would have recorded (the scenario's PLC, drives, faults and
            line errors), or serve that line on a pseudo-terminal for `sniffer detect` and `sniffer live`
            without hardware.""",
        examples=["sniffer simulate --out sample.mcap --scenario errors --duration 30 --seed 4",
                  "sniffer simulate --out day.mcap --rotate 1h --duration 1d --scenario fast",
                  "sniffer simulate --pty /tmp/line1 --scenario tds-v8 --baud 19200 --parity E"])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--out", metavar="FILE", help="FILE.mcap or FILE.csv (a folder, with --rotate)")
    g.add_argument("--pty", metavar="PATH",
                   help="serve the line on a pseudo-terminal, linked at PATH, until stopped (Ctrl-C): what a "
                        "UART at the settings a program sets there receives (`sniffer detect PATH`, `live PATH`)")
    scenario_flags(p)
    capture_duration_flag(p, "bus traffic to simulate: 30 (seconds), 10min, 1d (default: 10 s; with --pty: "
                             "until stopped)")
    p.add_argument("--adapter", choices=["wire", "usb"], default="usb",
                   help="timestamps per byte (a logic analyzer: wire) or per USB read (usb)")
    p.add_argument("--param", action="append", metavar="KEY=VALUE",
                   help="change the scenario: a setting (poll_period_ms=50) or a unit's (unit2.rated_current_a=7.5)")
    fault_flag(p, "put a cause of trouble on the line (repeatable: several at once), one `sniffer diagnose` names: "
                  "e.g. driver_enable_late:2, bus_unbiased,0.007 (a stray character after 0.7 %% of the "
                  "transmissions), unit_silent:5@20-60 (only from 20 s to 60 s), noise_during_ramps:1,gross "
                  "(docs/diagnose.md lists them)")
    serial_flags(p, "sim")
    g = p.add_argument_group("receiver (--out): record what a sniffer set to other settings than the line's receives")
    g.add_argument("--receiver-baud", type=number(int, "--receiver-baud", 50, MAX_BAUD), metavar="BAUD",
                   help="the receiver's baud rate (default: the line's)")
    g.add_argument("--receiver-parity", choices=["N", "E", "O"], type=str.upper,
                   help="the receiver's parity (default: the line's)")
    g.add_argument("--receiver-stopbits", type=int, choices=[1, 2], help="the receiver's stop bits (default: the "
                   "line's)")
    unattended_flags(p)
    foxglove_flags(p)


def run(spec: CaptureSpec, args) -> int:
    from sniffer.simulator import faults
    from sniffer.simulator.overrides import apply
    from sniffer.simulator.sources import SimulatedSource, scenario_named

    scenario = faults.apply(apply(scenario_named(spec.scenario or "default"), args.param), args.fault)
    base = scenario.line
    f = spec.flags
    line = LineSettings(f.baud or base.baud, f.parity or base.parity, f.stopbits or base.stopbits, base.databits)
    if args.pty:
        need_posix_tty("simulate --pty (a pseudo-terminal)")
        return _serve(scenario, line, spec.seed, spec.duration_s, args.pty)
    out = spec.out
    if spec.rotate is not None:
        fmt = "segments"  # a simulated day as an unattended capture writes it (--rotate 1h --out FOLDER)
    elif out.endswith(".csv"):
        fmt = "bytecsv"
    elif out.endswith(".mcap"):
        fmt = "mcap"
    else:
        raise UsageError("--out must end in .mcap or .csv (or name a folder, with --rotate)")
    duration = spec.duration_s if args.duration is not None else 10.0
    if duration <= 0:
        raise UsageError("--duration must be more than 0 seconds")
    receiver = None
    if args.receiver_baud or args.receiver_parity or args.receiver_stopbits:
        if any(k == "wrong_line_settings" for k, _ in scenario.faults):
            raise UsageError("--fault wrong_line_settings sets the receiver: not with --receiver-*")
        receiver = LineSettings(args.receiver_baud or line.baud, args.receiver_parity or line.parity,
                                args.receiver_stopbits or line.stopbits, line.databits)
    source = SimulatedSource(scenario, line, duration, spec.seed, args.adapter, receiver=receiver)
    recorded = receiver or faults.receiver_for(scenario, line) or line
    if fmt == "segments":
        from sniffer.formats.mcap.rotating import SegmentPlan

        sink = SegmentPlan(out, spec.rotate, spec.keep, inputs=spec.read_paths(), timed_flush=False)
    else:  # the simulated capture's bytes depend on the scenario and seed alone, not on the machine's load
        sink = FileSink(fmt, out, inputs=spec.read_paths(), timed_flush=False)
    # the simulated bus is what it is: the flags set its line, the scenario its protocol and drives
    session = Session(spec.with_(duration_s=0.0), source, [sink], keep_partial=True, label=f"simulate {scenario.name}")
    session.run()
    if session.error:
        return report(session)
    if fmt == "bytecsv":
        flags = f"--baud {recorded.baud} --parity {recorded.parity} --stopbits {recorded.stopbits}"
        if scenario.protocol != "modbus-rtu":
            flags += f" --protocol {scenario.protocol}"
        flags += "".join(f" --device {u}={m}" for u, m in sorted(scenario.devices.items()))
        say(f"wrote {session.bytes_in} bytes of scenario '{scenario.name}' at {_at(line, receiver)} to {out} "
            f"(replay with {flags})")
    else:
        where = session.sinks[0].written_text if fmt == "segments" else out
        say(f"wrote {session.frames_out} frames ({session.bytes_in} bytes) of scenario '{scenario.name}' "
            f"at {_at(line, receiver)} to {where}")
    return report(session)


def _at(line: LineSettings, receiver: LineSettings | None) -> str:
    return line.label() + (f", received at {receiver.label()}" if receiver and receiver != line else "")


def _serve(scenario, line: LineSettings, seed: int, duration_s: float, path: str) -> int:
    """The line on a pty linked at `path`, until stopped (or `duration_s`, if given)."""
    from sniffer.simulator.uartpty import PtyLine

    if os.path.lexists(path):
        if not (os.path.islink(path) and os.readlink(path).startswith("/dev/pts/")):
            raise UsageError(f"--pty {path}: exists; give a free path for the link")
        os.remove(path)  # the link of a simulated line that was killed
    stop = threading.Event()
    on_signals(stop)
    with PtyLine(scenario, line, seed, duration_s) as pty:
        pty.link(path)
        say(f"simulated line '{scenario.name}' at {line.label()} {scenario.protocol} on {path} (-> {pty.port}); "
            f"Ctrl-C stops")
        pty.play(stop)
        back = pty.bytes_received_from_sniffer
    say(f"stopped after {pty.frames_sent} frames; {back} bytes came from the other end (a passive sniffer sends none)")
    return 0
