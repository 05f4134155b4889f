"""`sniffer demo`: a live capture of a simulated bus over a pseudo-terminal (commands/capture.py runs it)."""

from __future__ import annotations

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.capture import run_capture
from sniffer.commands.common import UsageError, need_posix_tty, say, tui_wanted
from sniffer.commands.flags import (
    capture_out_flags, child_flag, command_parser, fault_flag, decode_flags, foxglove_flags, headless_flag, mqtt_flags,
    publish_flags, scenario_flags, stream_flags, trigger_flags, unattended_flags,
)


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "demo", help="live capture of a simulated bus over a pseudo-terminal",
        description="""\
            A simulated PLC polling simulated drives, sent over a pseudo-terminal and captured as `sniffer
            live` captures a port: the TUI on a terminal (q, then y, stops), frame lines otherwise.  No
            hardware needed; the scenarios cover every drive model and protocol the sniffer decodes.""",
        examples=["sniffer demo",
                  "sniffer demo --scenario errors --headless --duration 30",
                  "sniffer demo --scenario tds-v8 --trigger fault --out tds.mcap"])
    scenario_flags(p)
    fault_flag(p, "put a cause of trouble on the line (repeatable; docs/diagnose.md): its verdict shows in the "
                  "TUI's Verdicts tab (7)")
    capture_out_flags(p, "demo.mcap", 15.0)
    headless_flag(p)
    decode_flags(p, "sim")
    stream_flags(p, quiet="the MCAP file, --publish and --mqtt only")
    publish_flags(p)
    unattended_flags(p)
    trigger_flags(p)
    foxglove_flags(p)
    mqtt_flags(p)
    child_flag(p)


def run(spec: CaptureSpec, args) -> int:
    from sniffer.simulator.faults import apply
    from sniffer.simulator.sources import DemoSource, scenario_named

    scenario = apply(scenario_named(spec.scenario or "default"), spec.faults)  # a bad --fault: one line, now
    if any(kind == "wrong_line_settings" for kind, _ in scenario.faults):
        raise UsageError("demo reads the line at its own settings: for wrong_line_settings use `sniffer simulate "
                         "--fault wrong_line_settings`, or `simulate --pty` and `live` at other settings")
    need_posix_tty("demo (a simulated bus on a pseudo-terminal)")
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "demo", f"demo {scenario.name}")
    source = DemoSource(scenario, spec.seed, spec.duration_s)
    # the bus ends the demo (DemoSource stops after the scenario's duration): no deadline of the session's own
    rc = run_capture(spec.with_(duration_s=0.0), source, f"demo {scenario.name}",
                     what=lambda: f"demo '{scenario.name}' on simulated bus {source.port}",
                     status_label=f"demo {scenario.name}")
    if source.stats is not None:
        say(f"simulator sent {source.stats.frames} frames ({source.stats.bytes} bytes); "
            f"sniffer wrote {source.bytes_written_back} bytes to the bus")
    return rc
