"""`sniffer attach SOCKET` (a viewer of a capture running elsewhere) and `sniffer serve` (viewers in browsers)."""

from __future__ import annotations

from sniffer import need
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import UsageError, tui_wanted


def cmd_attach(spec: CaptureSpec, args) -> int:
    from sniffer.processes.attach import Attachment, run_headless
    from sniffer.tui.run import attach_tui

    if getattr(args, "exit_with_parent", False):  # a browser's viewer under `sniffer serve`
        import signal

        from sniffer.processes.parent_death import die_with_parent

        die_with_parent(signal.SIGKILL)
    att = Attachment(args.socket)  # no capture there: CaptureError, one line, exit 2
    if args.tui or tui_wanted(spec):
        return attach_tui(att)
    return run_headless(att, args.format)


def cmd_serve(spec: CaptureSpec, args) -> int:
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
