"""CLI glue for `sniffer check`, `sniffer diff` and `sniffer export` (wired in sniffer/cli.py).

    add_parsers(sub, serial_flags, decode_flags)   # cli._serial_flags, cli._decode_flags
    COMMANDS = {"check": cmd_check, "diff": cmd_diff, "export": cmd_export}

Exit codes: check 0 same / 1 different / 2 error; diff 0 no semantic
difference / 1 different / 2 error; export 0 / 2 error / 130 Ctrl-C (the
output file is closed and valid up to the interruption).
"""

from __future__ import annotations

import argparse
import sys

from . import FORMATS

INPUT_FORMATS = ["auto", "mcap", "csv", "saleae", "pcap"]


def add_parsers(sub, serial_flags, decode_flags) -> None:
    s = sub.add_parser("check", help="decode a capture and compare it with its golden text (exit 0 same, 1 diff)")
    s.add_argument("file")
    s.add_argument("--golden", required=True, metavar="FILE.txt", help="the reviewed golden decode")
    s.add_argument("--update-golden", action="store_true", help="rewrite the golden (review the diff!)")
    s.add_argument("--time-tol-ms", type=float, default=1.0, help="frame time tolerance (default 1 ms)")
    s.add_argument("--latency-tol-ms", type=float, default=1.0, help="latency tolerance (default 1 ms)")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("diff", help="what changed between two captures: units, polls, registers, errors, latency")
    s.add_argument("a")
    s.add_argument("b")
    s.add_argument("--format", choices=["text", "json"], default="text", help="output format (default text)")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("export", help="decode a capture into csv, parquet, pcap (Wireshark) or mcap")
    s.add_argument("file")
    s.add_argument("--to", required=True, choices=FORMATS, help="output format")
    s.add_argument("--out", required=True, metavar="PATH", help="output file (csv/parquet: also PATH stem.points.*)")
    s.add_argument("--progress", action="store_true", help="show a progress line on stderr")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    serial_flags(s)
    decode_flags(s)


def options_from_args(args: argparse.Namespace):
    """DecodeOptions from the replay flags (--baud/--parity/--stopbits, --device, --bus, ...)."""
    from decoders.registry import parse_device_args

    from ..regress import DecodeOptions

    bus = None
    if getattr(args, "bus", None):
        from ..busfile import load_bus_file

        bus = load_bus_file(args.bus)
    devices = dict(bus.devices) if bus else {}
    devices.update(parse_device_args(getattr(args, "device", None)))
    return DecodeOptions(
        baud=getattr(args, "baud", None) or (bus.baud if bus else None),
        parity=getattr(args, "parity", None) or (bus.parity if bus else None),
        stopbits=getattr(args, "stopbits", None) or (bus.stopbits if bus else None),
        devices=devices,
        model_files=list(getattr(args, "model_file", None) or []),
        protocol=getattr(args, "protocol", None) or (bus.protocol if bus else None),
        timeout_ms=getattr(args, "timeout_ms", None),
        unit_timeouts=dict(bus.timeouts_ms) if bus else {},
        input_format=getattr(args, "input_format", "auto"),
    )


def cmd_check(args) -> int:
    from ..regress import Tolerances, check

    rc, text = check(args.file, args.golden, update=args.update_golden, options=options_from_args(args),
                     tolerances=Tolerances(args.time_tol_ms, args.latency_tol_ms))
    (sys.stdout if rc == 1 else sys.stderr).write(text)
    return rc


def cmd_diff(args) -> int:
    import orjson

    from ..regress import diff
    from ..sources import CaptureError

    try:
        report = diff(args.a, args.b, options_from_args(args))
    except (CaptureError, ValueError, OSError) as e:
        print(f"sniffer diff: error: {e}", file=sys.stderr)
        return 2
    if args.format == "json":
        sys.stdout.write(orjson.dumps(report.to_dict(), option=orjson.OPT_INDENT_2).decode() + "\n")
    else:
        sys.stdout.write(report.to_text())
    return 0 if report.same else 1


def cmd_export(args) -> int:
    from . import export

    n = export(args.file, args.to, args.out, options_from_args(args), progress=args.progress)
    print(f"sniffer: wrote {args.out} ({n} frames)", file=sys.stderr)
    return 0


COMMANDS = {"check": cmd_check, "diff": cmd_diff, "export": cmd_export}
