"""Command line: live, replay, decode, simulate, demo, repair, attach, serve.

Bad input gets one clear line on stderr and a non-zero exit (2 for usage
and unreadable input), never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys

from . import __version__
from .events import CaptureInfo, Chunk
from .line import LineSettings, SettingsError
from .pairer import DEFAULT_TIMEOUT_MS
from .sources import CaptureError

EXIT_USAGE = 2
from .protocols import NAMES as PROTOCOLS


class UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, not usage + line
        raise UsageError(message)


def _serial_flags(p: argparse.ArgumentParser, required: bool = False) -> None:
    g = p.add_argument_group("serial line")
    g.add_argument("--baud", type=int, help="baud rate (e.g. 9600, 19200, 115200)")
    g.add_argument("--parity", choices=["N", "E", "O"], type=str.upper, help="parity (default N)")
    g.add_argument("--stopbits", type=int, choices=[1, 2], help="stop bits (default 1)")


def _decode_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("decoding")
    g.add_argument("--device", action="append", metavar="UNIT=MODEL",
                   help="decode UNIT with MODEL (repeatable), e.g. --device 2=a510")
    g.add_argument("--bus", metavar="FILE", help="bus file (TOML): serial settings, unit models, timeouts")
    g.add_argument("--timeout-ms", type=float, default=None,
                   help=f"response timeout per unit (default {DEFAULT_TIMEOUT_MS:.0f} ms)")
    g.add_argument("--model-file", action="append", metavar="FILE.toml",
                   help="a drive's register map (docs/register-map-format.md); its [model] id becomes a model")
    g.add_argument("--protocol", choices=PROTOCOLS, default=None,
                   help="line protocol (default modbus-rtu, or what the capture says)")


def _publish_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("viewers in other processes")
    g.add_argument("--publish", metavar="SOCKET",
                   help="publish the frames on a Unix socket (mode 0600) for `sniffer attach SOCKET`; "
                        "tcp:[HOST:]PORT for TCP (host default 127.0.0.1)")
    g.add_argument("--publish-backlog", type=int, default=100_000, metavar="N",
                   help="frames a viewer that joins late gets first (default 100000)")
    p.add_argument("--quiet", action="store_true", help="no frame lines on stdout (the MCAP and --publish only)")


def _format_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--format", choices=["text", "jsonl"], default="text", help="output format (default text)")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="sniffer", description="Passive RS-485 sniffer for PLC <-> drive links (Modbus RTU).")
    p.add_argument("--version", action="version", version=f"sniffer {__version__}")
    sub = p.add_subparsers(dest="cmd", metavar="COMMAND", parser_class=_Parser)

    s = sub.add_parser("live", help="capture a serial port (read-only) and decode live")
    s.add_argument("port", help="serial device, e.g. /dev/ttyUSB0")
    _serial_flags(s)
    _decode_flags(s)
    _format_flag(s)
    s.add_argument("--out", metavar="FILE.mcap", help="MCAP file to write (default: sniffer-<time>.mcap)")
    s.add_argument("--no-out", action="store_true", help="do not write an MCAP file")
    s.add_argument("--duration", type=float, default=0, help="stop after S seconds (default: until Ctrl-C)")
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI (default off a tty)")
    _publish_flags(s)

    s = sub.add_parser("replay", help="decode a capture file (MCAP, byte CSV, Saleae CSV)")
    s.add_argument("file")
    s.add_argument("--input-format", choices=["auto", "mcap", "csv", "saleae", "pcap"], default="auto")
    s.add_argument("--progress", action="store_true", help="progress bar on stderr (frames/s, ETA for MCAP)")
    s.add_argument("--tui", action="store_true", help="browse the capture in the terminal UI")
    _serial_flags(s)
    _decode_flags(s)
    _format_flag(s)

    s = sub.add_parser("decode", help="decode frames given as hex, one argument per frame")
    s.add_argument("hex", nargs="+", help="frame bytes in hex, e.g. 010300000002C40B")
    s.add_argument("--baud", type=int, default=9600, help=argparse.SUPPRESS)
    _decode_flags(s)
    _format_flag(s)

    s = sub.add_parser("simulate", help="write a simulated capture (MCAP or byte CSV by extension)")
    s.add_argument("--out", required=True, metavar="FILE", help="FILE.mcap or FILE.csv")
    s.add_argument("--scenario", default="default")
    s.add_argument("--duration", type=float, default=10.0, help="seconds of bus traffic (default 10)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--adapter", choices=["wire", "usb"], default="usb",
                   help="timestamps per byte (logic analyzer) or per USB read (default usb)")
    s.add_argument("--param", action="append", metavar="KEY=VALUE",
                   help="change the scenario: a setting (poll_period_ms=50) or a unit's (unit2.rated_current_a=7.5)")
    _serial_flags(s)

    s = sub.add_parser("demo", help="live capture of a simulated bus over a pseudo-terminal")
    s.add_argument("--scenario", default="default")
    s.add_argument("--duration", type=float, default=15.0, help="seconds (default 15; 0 = until Ctrl-C)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--out", default="demo.mcap", metavar="FILE.mcap", help="MCAP file (default demo.mcap)")
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI")
    _format_flag(s)
    _publish_flags(s)

    s = sub.add_parser("attach", help="view a capture that another process publishes (--publish, sniffer serve)")
    s.add_argument("socket", help="the capture's socket (or tcp:[HOST:]PORT)")
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI (default off a tty)")
    s.add_argument("--tui", action="store_true", help="the TUI even without a terminal (sniffer serve uses it)")
    _format_flag(s)

    s = sub.add_parser("serve", help="serve the TUI to browsers (textual-serve); the capture runs on its own")
    s.add_argument("port", nargs="?", help="serial device to capture, e.g. /dev/ttyUSB0 (or --demo)")
    s.add_argument("--demo", action="store_true", help="capture the simulated bus of `sniffer demo` instead")
    s.add_argument("--scenario", default="default", help="with --demo: the scenario (default default)")
    s.add_argument("--seed", type=int, default=1, help=argparse.SUPPRESS)
    _serial_flags(s)
    _decode_flags(s)
    s.add_argument("--out", metavar="FILE.mcap",
                   help="MCAP file the capture writes (default: sniffer-<time>.mcap, demo.mcap with --demo)")
    s.add_argument("--no-out", action="store_true", help="do not write an MCAP file")
    s.add_argument("--duration", type=float, default=0, help="stop capturing after S seconds (default: until Ctrl-C)")
    g = s.add_argument_group("serving")
    g.add_argument("--host", default="127.0.0.1",
                   help="address to serve on (default 127.0.0.1: this machine only)")
    g.add_argument("--http-port", type=int, default=8000, help="HTTP port (default 8000)")
    g.add_argument("--public-url", help="URL browsers use to reach the server (when behind a proxy or --host 0.0.0.0)")
    g.add_argument("--socket", metavar="PATH",
                   help="where the capture publishes (default: a fresh one in $XDG_RUNTIME_DIR or /tmp)")
    g.add_argument("--publish-backlog", type=int, default=100_000, metavar="N",
                   help="frames a viewer that joins late gets first (default 100000)")

    s = sub.add_parser("repair", help="make a truncated (killed) capture readable by any MCAP reader")
    s.add_argument("file")
    s.add_argument("-o", "--out", help="output file (default: FILE.repaired.mcap)")

    from .export.commands import add_parsers as add_check_diff_export

    add_check_diff_export(sub, _serial_flags, _decode_flags)
    return p


# ---------------------------------------------------------------- helpers
def _line(args, info: CaptureInfo | None, bus, *, need: bool) -> LineSettings:
    baud = args.baud or (bus.baud if bus else None) or (info.baud if info else None)
    parity = args.parity or (bus.parity if bus else None) or (info.parity if info else None) or "N"
    stop = args.stopbits or (bus.stopbits if bus else None) or (info.stopbits if info else None) or 1
    if baud is None:
        if need:
            raise UsageError("this capture does not say its baud rate: give --baud (and --parity/--stopbits)")
        baud = 9600
    databits = (info.databits if info and info.databits else 8)
    return LineSettings(int(baud), str(parity).upper(), int(stop), int(databits))


def _bus(args):
    if getattr(args, "bus", None):
        from .busfile import load_bus_file

        return load_bus_file(args.bus)
    return None


def _registry(args, bus, info: CaptureInfo | None = None):
    from decoders.registry import default_registry, parse_device_args

    devices = dict(info.devices) if info and info.devices else {}
    if bus:
        devices.update(bus.devices)
    devices.update(parse_device_args(args.device))
    # units on a PD-series line speak PD whether mapped or not
    default = "pd-series" if _protocol(args, bus, info).startswith("pd-") else "generic"
    return default_registry(devices, getattr(args, "model_file", None), default=default)


def _protocol(args, bus, info: CaptureInfo | None = None) -> str:
    return (getattr(args, "protocol", None) or (bus.protocol if bus else None)
            or (info.protocol if info else None) or "modbus-rtu")


def _timeouts(args, bus) -> dict:
    kw = {"timeout_ms": args.timeout_ms if args.timeout_ms is not None else DEFAULT_TIMEOUT_MS,
          "protocol": _protocol(args, bus)}
    if bus and bus.timeouts_ms:
        kw["unit_timeouts"] = bus.timeouts_ms
    return kw


def _out_sink(args, line_buffered: bool):
    if args.format == "jsonl":
        from .sinks.jsonl import JsonlSink

        return JsonlSink(sys.stdout.buffer, flush=line_buffered)
    from .sinks.text import TextSink

    return TextSink(sys.stdout, flush=line_buffered)


# ---------------------------------------------------------------- commands
def cmd_replay(args) -> int:
    from .pipeline import Pipeline
    from .sources.replay import open_replay

    bus = _bus(args)
    info, events = open_replay(args.file, args.input_format)
    if info.extra.get("mcap_unfinished"):
        print(f"sniffer: note: {args.file} was not closed cleanly (capture killed?); read up to its last "
              f"complete record. 'sniffer repair {args.file}' writes a clean copy.", file=sys.stderr)
    line = _line(args, info, bus, need=True)
    registry = _registry(args, bus, info)
    kw = _timeouts(args, bus)
    kw["protocol"] = _protocol(args, bus, info)
    if args.tui:
        from .tui.run import replay_tui

        return replay_tui(args.file, info, events, line, registry, **kw)
    p = Pipeline(info, line, registry, [_out_sink(args, False)], **kw)
    bar = None
    if args.progress:
        from .progress import ReplayProgress

        bar = ReplayProgress(args.file, events=events)
        bar.frames = lambda: p.frames_out
    try:
        for i, ev in enumerate(events):
            p.feed(ev)
            if bar is not None:
                bar.update(i, ev)
    finally:
        if bar is not None:
            bar.close()
        p.finish()
    return 0


def cmd_decode(args) -> int:
    from .pipeline import Pipeline

    bus = _bus(args)
    line = LineSettings(args.baud)
    frames = []
    ascii_mode = _protocol(args, bus).endswith("-ascii")
    for h in args.hex:
        if ascii_mode:  # the frame as its characters: ':0103...' (CR LF added if missing)
            text = h.strip()
            data = (text if text.startswith(":") else ":" + text).encode("ascii", "replace")
            data += b"" if data.endswith(b"\r\n") else b"\r\n"
        else:
            text = h.replace(" ", "").replace(":", "")
            try:
                data = bytes.fromhex(text)
            except ValueError:
                raise UsageError(f"not hex: {h!r}") from None
        if data:
            frames.append(data)
    info = CaptureInfo(source="decode", baud=line.baud, parity=line.parity, stopbits=line.stopbits)
    p = Pipeline(info, line, _registry(args, bus), [_out_sink(args, False)], **_timeouts(args, bus))
    t = 0
    gap = 10 * line.t35_ns  # each argument is its own burst on the line
    for data in frames:
        times = tuple(t + i * line.char_ns for i in range(len(data)))
        p.feed(Chunk(t, data, times))
        t = times[-1] + line.char_ns + gap
    p.finish()
    return 0


def cmd_repair(args) -> int:
    from .mcap_repair import default_output, repair

    out = args.out or default_output(args.file)
    if not os.path.exists(args.file):
        raise CaptureError(f"{args.file}: no such file")
    st = repair(args.file, out)
    print(f"sniffer: wrote {out}: {st['messages']} messages kept, {st['bytes_dropped']} bytes dropped"
          f"{' (' + st['problem'] + ')' if st.get('problem') else ''}", file=sys.stderr)
    return 0


def _tui_wanted(args) -> bool:
    """The TUI is the default on a terminal; --headless, --quiet, --format jsonl or a pipe keep the stream."""
    return (not args.headless and not getattr(args, "quiet", False) and args.format == "text"
            and sys.stdout.isatty() and sys.stdin.isatty())


def cmd_live(args) -> int:
    if _tui_wanted(args):
        from .tui.run import live_tui

        return live_tui(args, _bus(args), _line, _registry, _timeouts)
    from .live import run_live

    return run_live(args, _bus(args), _line, _registry, _timeouts, _out_sink)


def cmd_simulate(args) -> int:
    from .simulate_cmd import run_simulate

    return run_simulate(args)


def cmd_demo(args) -> int:
    if _tui_wanted(args):
        from .tui.run import demo_tui

        return demo_tui(args, _registry)
    from .live import run_demo

    return run_demo(args, _registry, _out_sink)


def cmd_attach(args) -> int:
    from .attach import Attachment, attach_tui, run_headless

    att = Attachment(args.socket)  # no capture there: CaptureError, one line, exit 2
    if args.tui or _tui_wanted(args):
        return attach_tui(att)
    return run_headless(att, args.format)


def cmd_serve(args) -> int:
    from .serve import ServeUsageError, run_serve

    try:
        return run_serve(args)
    except ServeUsageError as e:
        raise UsageError(str(e)) from None


COMMANDS = {
    "live": cmd_live, "replay": cmd_replay, "decode": cmd_decode,
    "simulate": cmd_simulate, "demo": cmd_demo, "repair": cmd_repair,
    "attach": cmd_attach, "serve": cmd_serve,
}


def _check_diff_export():
    from .export.commands import COMMANDS as extra

    return extra


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not args.cmd:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        commands = {**COMMANDS, **_check_diff_export()}
        return commands[args.cmd](args)
    except UsageError as e:
        print(f"sniffer: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except (CaptureError, SettingsError) as e:
        print(f"sniffer: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except ValueError as e:  # device map, bus file, register map
        from decoders.registry import DeviceMapError
        from decoders.tables import MapError
        from .busfile import BusFileError

        from .simulator.overrides import OverrideError

        if isinstance(e, (DeviceMapError, BusFileError, MapError, OverrideError)):
            print(f"sniffer: error: {e}", file=sys.stderr)
            return EXIT_USAGE
        raise
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # output piped into `head` etc.: stop quietly
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except OSError as e:  # e.g. an output file that cannot be written
        print(f"sniffer: error: {e.filename + ': ' if e.filename else ''}{e.strerror or e}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
