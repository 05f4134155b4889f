"""`sniffer extcap`: Wireshark's extcap interface (sniffer/extcap/), and `--install` to put its launcher where
Wireshark looks."""

from __future__ import annotations

import sys

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK, UsageError, say
from sniffer.commands.flags import command_parser


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "extcap",
        help="capture in Wireshark: the extcap interface Wireshark and tshark run (--install puts it in place)",
        description="""\
            Wireshark's extcap interface: Wireshark and tshark list every serial adapter
            (/dev/serial/by-id), sigrok logic analyzer and bus file as a capture interface and capture it
            live as Modbus RTU (link type 147), each packet with a comment of the registers by name and
            value, CRC and UART notes, the pair and latency.  Read-only, as `live`.  `--install` writes
            the launcher into your personal extcap folder; restart Wireshark.""",
        examples=["sniffer extcap --install",
                  "sniffer extcap --install --list-port socket://10.0.0.7:4001 --list-bus plant.toml",
                  "sniffer extcap --extcap-interfaces --no-sigrok      # what Wireshark lists"])
    p.add_argument("--install", action="store_true", help="write the launcher into the personal extcap folder")
    p.add_argument("--folder", dest="x_folder", metavar="DIR", help="with --install: this folder instead")
    p.add_argument("--list-port", dest="x_ports", action="append", default=[], metavar="PORT",
                   help="a port or gateway URL to list as an interface too (repeatable; --install keeps it)")
    p.add_argument("--list-bus", dest="x_buses", action="append", default=[], metavar="FILE",
                   help="a bus file to list as an interface (its [[links]]; repeatable; --install keeps it)")
    p.add_argument("--no-sigrok", dest="x_no_sigrok", action="store_true", help="do not look for logic analyzers")
    g = p.add_argument_group("the extcap interface (Wireshark passes these)")
    g.add_argument("--extcap-interfaces", action="store_true")
    g.add_argument("--extcap-version", nargs="?", const="", default=None)
    g.add_argument("--extcap-dlts", action="store_true")
    g.add_argument("--extcap-config", action="store_true")
    g.add_argument("--extcap-interface", metavar="VALUE")
    g.add_argument("--capture", action="store_true")
    g.add_argument("--fifo", metavar="PATH")
    g.add_argument("--extcap-capture-filter", metavar="FILTER")
    g.add_argument("--extcap-reload-option", metavar="OPTION")
    g.add_argument("--debug", action="store_true")
    g.add_argument("--debug-file", metavar="FILE")
    d = p.add_argument_group("the capture dialog (Wireshark passes them; tshark: -o extcap.IFACE.linebaud:19200)")
    d.add_argument("--line-baud", dest="x_baud", default="detect", help="a baud rate, or detect (default)")
    d.add_argument("--line-parity", dest="x_parity", default="detect", help="N, E, O or detect (default)")
    d.add_argument("--line-stopbits", dest="x_stopbits", default="detect", help="1, 2 or detect (default)")
    d.add_argument("--line-bus", dest="x_bus", metavar="FILE", help="a bus file of the line's settings and models")
    d.add_argument("--line-rx", dest="x_rx", metavar="CHANNEL", help="a logic analyzer's receive channel (default D0)")


def run(spec: CaptureSpec, args) -> int:
    from sniffer.extcap import interfaces as ifs

    if args.install:
        from sniffer.extcap.install import install

        path = install(args.x_folder, args.x_ports, args.x_buses)
        say(f"wrote {path}: restart Wireshark; `tshark -D` lists the interfaces (docs/wireshark.md)")
        return EXIT_OK
    if args.extcap_interfaces or (args.extcap_version is not None and not args.extcap_interface):
        found = ifs.targets(args.x_ports, args.x_buses, sigrok=not args.x_no_sigrok)
        lines = ifs.interface_lines(found) if args.extcap_interfaces else [ifs.version_line()]
        return _print(lines)
    if not args.extcap_interface:
        raise UsageError("extcap: Wireshark runs this (see `sniffer extcap --help`); --install puts it in place")
    try:
        target = ifs.Target.parse(args.extcap_interface)
    except ValueError as e:
        raise UsageError(f"extcap: {e}") from None
    if args.extcap_dlts:
        return _print(ifs.dlt_lines())
    if args.extcap_config:
        return _print(ifs.config_lines(target))
    if args.capture:
        if not args.fifo:
            raise UsageError("extcap --capture: give --fifo PATH (Wireshark does)")
        _check(args, target)
        return _capture(target, args)
    raise UsageError("extcap: say what: --extcap-dlts, --extcap-config or --capture with --extcap-interface")


def _capture(target, args) -> int:
    """Detect first if the dialog says so, then `live --format pcapng` with its stdout on Wireshark's fifo."""
    import contextlib
    import os
    import tempfile

    from sniffer.extcap.capture import detect_argv, live_argv

    with tempfile.TemporaryDirectory(prefix="sniffer-extcap-") as tmp, _stderr_to(args.debug_file or
                                                                                 os.path.join(tmp, "log")):
        bus = args.x_bus
        listen = detect_argv(target, args.x_baud, args.x_parity, args.x_stopbits, bus, os.path.join(tmp, "line.toml"))
        if listen is not None:
            with contextlib.redirect_stdout(sys.stderr):  # its report is not for the fifo
                rc = _sniffer(listen)
            if rc != 0:
                raise SystemExit(rc)
            bus = listen[listen.index("--write-bus") + 1]
        argv = live_argv(target, args.x_baud, args.x_parity, args.x_stopbits, bus, args.x_rx)
        with open(args.fifo, "wb", buffering=0) as out:  # Wireshark reads the other end
            sys.stdout.flush()
            os.dup2(out.fileno(), sys.stdout.fileno())  # live's stream goes to stdout
        rc = _sniffer(argv)
        if rc != 0:
            raise SystemExit(rc)
        return rc


class _stderr_to:
    """Wireshark takes anything an extcap writes on stderr as an error ("Error by extcap pipe"): the capture's
    lines ("capturing ...", a port lost and back) go to a log instead (--debug-file if Wireshark gives one),
    and only the line of a capture that failed reaches Wireshark."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __enter__(self):
        import os

        sys.stderr.flush()
        self.saved = os.dup(2)
        self.log = open(self.path, "a", encoding="utf-8")
        os.dup2(self.log.fileno(), 2)
        return self

    def __exit__(self, kind, error, tb) -> None:
        import os

        sys.stderr.flush()
        os.dup2(self.saved, 2)
        os.close(self.saved)
        self.log.close()
        if kind is None:
            return
        # an error raised goes on to sniffer.cli (one line, on the real stderr now); a failed capture's own lines:
        # the last one says why
        if isinstance(error, SystemExit) and error.code:
            with open(self.path, encoding="utf-8", errors="replace") as f:
                tail = f.read().strip().splitlines()[-1:]
            sys.stderr.write("".join(line + "\n" for line in tail))


def _sniffer(argv: list[str]) -> int:
    """Run a sniffer command here; its errors are this one's (one line, sniffer.cli)."""
    from sniffer.commands import build_parser, run as run_command

    args = build_parser().parse_args(argv)
    return run_command(args.cmd, CaptureSpec.from_args(args), args)


def _check(args, target) -> None:
    """The dialog's values, checked before anything opens (one line each, Wireshark shows it)."""
    if target.kind == "sigrok" and args.x_baud == "detect":
        raise UsageError(f"{target.value}: a logic analyzer's capture needs its baud rate chosen in the dialog")
    if args.x_baud != "detect" and not args.x_baud.isdigit():
        raise UsageError(f"extcap: baud rate {args.x_baud!r}: a number or detect")
    if args.x_parity not in ("detect", "N", "E", "O"):
        raise UsageError(f"extcap: parity {args.x_parity!r}: N, E, O or detect")
    if args.x_stopbits not in ("detect", "1", "2"):
        raise UsageError(f"extcap: stop bits {args.x_stopbits!r}: 1, 2 or detect")


def _print(lines: list[str]) -> int:
    sys.stdout.write("".join(line + "\n" for line in lines))
    sys.stdout.flush()
    return EXIT_OK
