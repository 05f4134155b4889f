"""`sniffer live PORT` and `sniffer demo`: capture a line (read-only) or the simulated bus, into MCAP.

Whatever ends the capture (Ctrl-C, SIGTERM, --duration, the TUI's quit, a full
disk, the source failing) the pipeline is flushed and the MCAP closed and kept.
With the TUI the capture is a process of its own and the TUI a viewer of it
(tui/run.py run_capture_tui): the UI never shares the reader's interpreter.
"""

from __future__ import annotations

import sys

from sniffer.capture.session import Session, on_signals
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import (
    UsageError, capture_sinks, default_capture_name, destination, line_warning, report, say, summary_line,
    tui_wanted,
)


def cmd_live(spec: CaptureSpec, args) -> int:
    from sniffer.processes.reader import live_source

    from sniffer.sources.logic_options import is_device

    if not spec.port:
        raise UsageError("live: give a PORT (several for several links), --tap PORT_A PORT_B, "
                         "or a --bus file with [[links]]")
    if any(is_device(p) for plan in spec.links for p in plan.ports):
        raise UsageError("a logic analyzer (sigrok:DRIVER) is one capture of its own: give it alone")
    if is_device(spec.port) or spec.logic is not None:
        return _live_logic(spec)
    if not args.no_out and not spec.out:
        name = default_capture_name()
        spec = spec.with_(out=name[:-5] if spec.rotate is not None else name)
    if spec.links:  # several links, or a tapped one: each resolved now, before a port opens
        plans = [(plan, spec.resolve_link(plan.name, need_baud=False).line) for plan in spec.links]
        label = " ".join(plan.name for plan in spec.links)
        ports = [p for plan in spec.links for p in plan.ports]
        if tui_wanted(spec):
            from sniffer.tui.run import run_capture_tui

            return run_capture_tui(spec, "live", label)
        return _capture(spec, live_source("links", plans), label, inputs=ports,
                        what=lambda: f"capturing {len(plans)} links: " + "; ".join(
                            f"{p.name} ({' + '.join(p.ports)}{', tapped' if p.tap else ''})" for p, _ in plans))
    line = spec.resolve(None, need_baud=False).line  # flags > bus file > defaults: the port's settings
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "live", spec.port)
    source = live_source("serial", spec.port, line)
    return _capture(spec, source, spec.port, inputs=[spec.port], status_label=f"live {spec.port}")


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
    return _capture(spec, source, str(device), what=lambda: what, status_label=f"live {device}")


def cmd_demo(spec: CaptureSpec, args) -> int:
    from sniffer.simulator.sources import DemoSource, scenario_named

    if args.no_out:
        spec = spec.with_(out=None)
    from sniffer.simulator.faults import apply

    scenario = apply(scenario_named(spec.scenario or "default"), spec.faults)  # a bad --fault: one line, now
    if any(kind == "wrong_line_settings" for kind, _ in scenario.faults):
        raise UsageError("demo reads the line at its own settings: for wrong_line_settings use `sniffer simulate "
                         "--fault wrong_line_settings`, or `simulate --pty` and `live` at other settings")
    if tui_wanted(spec):
        from sniffer.tui.run import run_capture_tui

        return run_capture_tui(spec, "demo", f"demo {scenario.name}")
    source = DemoSource(scenario, spec.seed, spec.duration_s)
    # the bus ends the demo (DemoSource stops after the scenario's duration): no deadline of the session's own
    rc = _capture(spec.with_(duration_s=0.0), source, f"demo {scenario.name}",
                  what=lambda: f"demo '{scenario.name}' on simulated bus {source.port}",
                  status_label=f"demo {scenario.name}")
    if source.stats is not None:
        say(f"simulator sent {source.stats.frames} frames ({source.stats.bytes} bytes); "
            f"sniffer wrote {source.bytes_written_back} bytes to the bus")
    return rc


def capture_session(spec: CaptureSpec, source, label: str, *, inputs=(), status_label: str = "") -> Session:
    """The session of a capture: the stdout stream, the MCAP file, the viewers' socket; its files are kept
    whatever ends it.  Outputs are checked now; nothing is opened yet."""
    sinks = [line_warning(), *capture_sinks(spec, label, stream=True, inputs=inputs)]
    return Session(spec, source, sinks, keep_partial=True, need_baud=False, label=status_label or label)


def _capture(spec: CaptureSpec, source, label: str, inputs=(), what=None, status_label="") -> int:
    session = capture_session(spec, source, label, inputs=inputs, status_label=status_label)
    on_signals(session.stop)
    if spec.wait_port and inputs:  # a live capture's inputs are its ports: of every link, both of a --tap
        from sniffer.capture.status import wait_for_ports

        if not wait_for_ports(list(inputs), session.stop, session.status_path(), status_label or label):
            return report(session)  # stopped while waiting: nothing captured, nothing to say
    session.open()  # a missing port, a bad setting: one line, and nothing created
    links = getattr(session.pipeline, "resolved", None)
    at = ("; ".join(f"{name} at {r.describe()}" for name, r in links.items()) if links
          else f"at {session.resolved.describe()}")
    say(f"{what() if what else 'capturing ' + label} {at} (read-only){destination(spec, session)}")
    session.run()
    print(summary_line(session), file=sys.stderr)
    return report(session)
