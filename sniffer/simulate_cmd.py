"""`sniffer simulate`: write a simulated capture to MCAP or a byte CSV.

The capture holds what a device would have recorded: per-byte times (a
logic analyzer, --adapter wire) or per-read chunks of a USB adapter
(--adapter usb, the default, with glued and split frames).  An MCAP also
holds the decoded frames, like a live capture does, and says the scenario's
protocol and drive models, so a replay decodes with them by default.
"""

from __future__ import annotations

import sys

from . import __version__
from .events import CaptureInfo
from .line import LineSettings


def run_simulate(args) -> int:
    from decoders.registry import default_registry

    from .simulator.bus import simulate
    from .simulator.chunks import usb_chunks, wire_chunks
    from .simulator.scenario import get_scenario

    from .simulator.overrides import apply

    try:
        scenario = get_scenario(args.scenario)
    except ValueError as e:
        print(f"sniffer: error: {e}", file=sys.stderr)
        return 2
    scenario = apply(scenario, getattr(args, "param", None))
    base = scenario.line
    line = LineSettings(args.baud or base.baud, args.parity or base.parity, args.stopbits or base.stopbits,
                        base.databits)
    devices = dict(scenario.devices)
    frames = simulate(scenario, line, args.duration, args.seed)
    if args.adapter == "usb":
        events = usb_chunks(frames, seed=args.seed)
    else:
        events = wire_chunks(frames)
    out = args.out
    if out.endswith(".csv"):
        from .sources.bytecsv import write_byte_csv

        n = write_byte_csv(out, events)
        flags = f"--baud {line.baud} --parity {line.parity} --stopbits {line.stopbits}"
        if scenario.protocol != "modbus-rtu":
            flags += f" --protocol {scenario.protocol}"
        flags += "".join(f" --device {u}={m}" for u, m in sorted(devices.items()))
        print(f"sniffer: wrote {n} bytes of scenario '{scenario.name}' at {line.label()} to {out} "
              f"(replay with {flags})", file=sys.stderr)
        return 0
    if not out.endswith(".mcap"):
        print("sniffer: error: --out must end in .mcap or .csv", file=sys.stderr)
        return 2
    from .sinks.mcap import CaptureStorageError, McapSink
    from .pipeline import Pipeline

    info = CaptureInfo(
        source=f"simulator:{scenario.name}:seed={args.seed}", port="(simulated)", baud=line.baud,
        parity=line.parity, stopbits=line.stopbits, databits=line.databits,
        time_source="read" if args.adapter == "usb" else "byte",
        t0_ns=0, wall_anchor_ns=0, sniffer_version=__version__,
        low_latency={"simulated": True, "adapter": args.adapter},
        devices=devices, protocol=scenario.protocol,
    )
    sink = McapSink(out, flush_interval_s=3600)
    p = Pipeline(info, line, default_registry(devices), [sink], protocol=scenario.protocol)
    try:
        for ev in events:
            p.feed(ev)
    except CaptureStorageError as e:
        print(f"sniffer: error: {e}", file=sys.stderr)
        return 1
    finally:
        p.finish()
    print(f"sniffer: wrote {p.frames_out} frames ({p.bytes_in} bytes) of scenario '{scenario.name}' "
          f"at {line.label()} to {out}", file=sys.stderr)
    return 0
