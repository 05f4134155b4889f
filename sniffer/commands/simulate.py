"""`sniffer simulate`: write a simulated capture to MCAP or a byte CSV.

The capture holds what a device would have recorded: per-byte times (a
logic analyzer, --adapter wire) or per-read chunks of a USB adapter
(--adapter usb, the default, with glued and split frames).  An MCAP also
holds the decoded frames, like a live capture does, and says the scenario's
protocol and drive models, so a replay decodes with them by default.
"""

from __future__ import annotations

from ..line import LineSettings
from ..session import Session
from ..settings import CaptureSpec
from ..sinks import FileSink
from .common import UsageError, report, say


def cmd_simulate(spec: CaptureSpec, args) -> int:
    from ..simulator.overrides import apply
    from ..simulator.sources import SimulatedSource, scenario_named

    out = args.out
    if out.endswith(".csv"):
        fmt = "bytecsv"
    elif out.endswith(".mcap"):
        fmt = "mcap"
    else:
        raise UsageError("--out must end in .mcap or .csv")
    if spec.duration_s <= 0:
        raise UsageError("--duration must be more than 0 seconds")
    scenario = apply(scenario_named(spec.scenario or "default"), args.param)
    base = scenario.line
    f = spec.flags
    line = LineSettings(f.baud or base.baud, f.parity or base.parity, f.stopbits or base.stopbits, base.databits)
    source = SimulatedSource(scenario, line, spec.duration_s, spec.seed, args.adapter)
    sink = FileSink(fmt, out)
    # the simulated bus is what it is: the flags set its line, the scenario its protocol and drives
    session = Session(spec.with_(duration_s=0.0), source, [sink], keep_partial=True)
    session.run()
    if session.error:
        return report(session)
    if fmt == "bytecsv":
        flags = f"--baud {line.baud} --parity {line.parity} --stopbits {line.stopbits}"
        if scenario.protocol != "modbus-rtu":
            flags += f" --protocol {scenario.protocol}"
        flags += "".join(f" --device {u}={m}" for u, m in sorted(scenario.devices.items()))
        say(f"wrote {session.bytes_in} bytes of scenario '{scenario.name}' at {line.label()} to {out} "
            f"(replay with {flags})")
    else:
        say(f"wrote {session.frames_out} frames ({session.bytes_in} bytes) of scenario '{scenario.name}' "
            f"at {line.label()} to {out}")
    return report(session)
