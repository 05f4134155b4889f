"""Command line: parse the flags into a CaptureSpec (sniffer.capture.session) and run a command (sniffer.commands).

Every flag is declared once, in a group that the commands which take it share.
Bad input gets one clear line on stderr and exit code 2 (a capture that could
not be written: 1; Ctrl-C: 130), never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys

from sniffer import __version__
from sniffer.commands import command
from sniffer.commands.common import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_USAGE, UsageError
from sniffer.line import SettingsError
from sniffer.capture.pairer import DEFAULT_TIMEOUT_MS
from sniffer.protocols import NAMES as PROTOCOLS
from sniffer.dataset.query import PRESETS
from sniffer.formats import EXPORT_FORMATS
from sniffer.events import CaptureError
from sniffer.sources.files import FORMATS as INPUT_FORMATS
from sniffer.parallel.options import add_dask_flag, add_jobs_flag

MAX_BAUD = 4_000_000


class _Once(argparse.Action):
    """A flag that takes one value (argparse's plain store): given twice, the second would silently replace
    the first (`--bus a.toml --bus b.toml`: a link captured at the wrong settings), so it is refused."""

    def __call__(self, parser, namespace, values, option_string=None):
        if option_string is not None:
            given = namespace.__dict__.setdefault("_given_once", {})
            if self.dest in given:
                raise UsageError(f"{option_string} given twice ({_shown(given[self.dest])} and {_shown(values)}): "
                                 "it takes one value")
            given[self.dest] = values
        setattr(namespace, self.dest, values)


def _shown(v) -> str:
    from sniffer.formats.reading import quote

    return quote(" ".join(map(str, v)) if isinstance(v, list) else str(v))


class _Parser(argparse.ArgumentParser):
    def __init__(self, *a, **kw) -> None:
        super().__init__(*a, **kw)
        self.register("action", None, _Once)  # every single-value flag, in every subcommand
        self.register("action", "store", _Once)

    def parse_known_args(self, args=None, namespace=None):
        ns, rest = super().parse_known_args(args, namespace)
        ns.__dict__.pop("_given_once", None)
        return ns, rest

    def error(self, message: str):  # one line, not usage + line
        raise UsageError(message)


_SCENARIO_HELP = ("the simulated line (default: default): default, errors, fast, stress, tds-v8, a510, a510-ascii, "
                  "spl, spl-ascii, pd-series, pd-series-ascii")

_DETECT_HELP = """\
Listen to PORT (opened read-only: nothing is ever sent) at one setting after another
and say which baud rate, character format and protocol the line runs, with the
evidence: frames with a good CRC/LRC, request/response pairs, the UART's parity and
framing errors (the tty marks them), and whether the characters come as fast as the
format allows."""
_DETECT_EPILOG = """\
Tries 1200 ... 921600 baud (the common rates, most common first; --bauds adds others),
8N1 8E1 8O1 8N2 (and 7E1 7O1 7N2 for ASCII lines), Modbus RTU, Modbus ASCII and the
PD-series protocol, and stops as soon as one candidate is certain.

exit status: 0 the line is settled (printed; written with --write-bus), 1 no traffic
or no candidate fits (nothing is guessed, no file written), 2 bad flags or a port
that cannot be opened.

  sniffer detect /dev/ttyUSB0 --write-bus line.toml
  sniffer live /dev/ttyUSB0 --bus line.toml"""


def _number(kind, what: str, lo, hi):
    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            whole = "whole " if kind is int else ""
            raise argparse.ArgumentTypeError(f"{what} {text[:40]!r} is not a {whole}number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} {text[:40]} is outside {lo}..{hi}")
        return v

    return parse


# ---------------------------------------------------------------- flag groups (each declared once)
def port_flags(p: argparse.ArgumentParser, what: str = "") -> None:
    p.add_argument("ports", nargs="*", metavar="PORT",
                   help=f"serial device, e.g. /dev/ttyUSB0{what}; several: one link each, captured together "
                        "(one clock, one MCAP, a link column); or a --bus file's [[links]]")
    p.add_argument("--tap", nargs=2, action="append", metavar=("PORT_A", "PORT_B"),
                   help="one 4-wire link tapped by two receive-only adapters: the master's pair (requests) "
                        "on PORT_A, the slaves' pair (responses) on PORT_B, merged by time (repeatable)")


def serial_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("serial line")
    g.add_argument("--baud", type=_number(int, "baud rate", 1, MAX_BAUD), help="baud rate (e.g. 9600, 19200, 115200)")
    g.add_argument("--parity", choices=["N", "E", "O"], type=str.upper, help="parity (default N)")
    g.add_argument("--stopbits", type=int, choices=[1, 2], help="stop bits (default 1)")


def logic_flags(p: argparse.ArgumentParser, live: bool = False) -> None:
    g = p.add_argument_group("logic analyzer (a sigrok .sr capture, or live sigrok:DRIVER; docs/logic-analyzer.md)")
    g.add_argument("--rx", metavar="CHANNEL", help="the channel the line is on: what the probed slave receives "
                   "(alone: the half-duplex bus, both directions); e.g. D0")
    g.add_argument("--tx", metavar="CHANNEL", help="the slave's transmit line (4-wire, or both sides of a "
                   "transceiver): its bytes are responses, --rx's requests")
    g.add_argument("--de", metavar="CHANNEL", help="the slave's driver-enable: bytes sent while it is high are "
                   "responses; its turn-on/turn-off times go on the frames (de_on_ns, de_off_ns)")
    g.add_argument("--invert", action="store_true", help="the UART lines idle low (RS-232 side, inverting probe)")
    if live:
        g.add_argument("--samplerate", metavar="RATE", help="the analyzer's sample rate for live sigrok:DRIVER "
                       "(default 1M; at least 4 samples a bit): 1M, 4MHz, 24M")


def decode_flags(p: argparse.ArgumentParser, bus: bool = True) -> None:
    g = p.add_argument_group("decoding")
    g.add_argument("--device", action="append", metavar="UNIT=MODEL",
                   help="decode UNIT with MODEL (repeatable), e.g. --device 2=a510")
    if bus:
        g.add_argument("--bus", metavar="FILE", help="bus file (TOML): serial settings, unit models, timeouts")
    g.add_argument("--timeout-ms", type=float, default=None,
                   help=f"response timeout per unit (default {DEFAULT_TIMEOUT_MS:.0f} ms)")
    g.add_argument("--model-file", action="append", metavar="FILE",
                   help="a device's register map: TOML (docs/register-map-format.md), CSV or Home Assistant "
                        "modbus YAML; its model id (the file's stem unless it names one) becomes a model")
    g.add_argument("--map-base", choices=["0", "1", "modicon"], default=None,
                   help="how a CSV map counts its addresses: from 0 (default), from 1, or Modicon 4xxxx/3xxxx")
    g.add_argument("--protocol", choices=PROTOCOLS, default=None,
                   help="line protocol (default modbus-rtu, or what the capture says)")


def input_flags(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", nargs="+", help="capture file: MCAP, byte CSV, Saleae CSV, pcap/pcapng, a sigrok .sr "
                                          "(with --rx); several files, a rotated capture's folder or its "
                                          "index.json are read as one capture")
    p.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    logic_flags(p)


def stream_flags(p: argparse.ArgumentParser, quiet: bool = False) -> None:
    p.add_argument("--format", choices=["text", "jsonl"], default="text", help="output format (default text)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no frame lines on stdout (the MCAP and --publish only)")


def capture_out_flags(p: argparse.ArgumentParser, default_out: str | None, duration: float) -> None:
    g = p.add_argument_group("capture")
    g.add_argument("--out", default=default_out, metavar="FILE.mcap",
                   help=f"MCAP file to write (default: {default_out or 'sniffer-<time>.mcap'})")
    g.add_argument("--no-out", action="store_true", help="do not write an MCAP file")
    g.add_argument("--duration", type=float, default=duration,
                   help=f"stop after S seconds (default {duration:g}; 0 = until Ctrl-C)")


def unattended_flags(p: argparse.ArgumentParser, port: bool = False) -> None:
    g = p.add_argument_group("unattended capture (docs/unattended.md)")
    g.add_argument("--rotate", action="append", metavar="SIZE|TIME",
                   help="write the MCAP as segments in the folder --out names (FOLDER or FOLDER.mcap), a new one "
                        "after TIME of capture (30m, 1h, 1d: on the clock) or SIZE bytes (100MB, 2GB), whichever "
                        "comes first (1h,100MB or the flag twice); each segment replays alone, and "
                        "`sniffer replay FOLDER` replays them as one capture")
    g.add_argument("--keep", action="append", metavar="AGE|SIZE|N",
                   help="with --rotate: delete the oldest closed segments past AGE (7d, 12h), past SIZE in all "
                        "(20GB), or past N segments (repeatable: all apply); the open one never")
    g.add_argument("--status", metavar="FILE.json",
                   help="keep a status file (uptime, frames, errors, segments, disk use) for `sniffer status`; "
                        "default with --rotate: status.json in the capture's folder")
    if port:
        g.add_argument("--wait-port", action="store_true",
                       help="a port that is not there yet (adapter not plugged in, boot) is waited for instead "
                            "of an error; an adapter unplugged during the capture is always waited for")


def publish_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("viewers in other processes")
    g.add_argument("--publish", metavar="SOCKET",
                   help="publish the frames on a Unix socket (mode 0600) for `sniffer attach SOCKET`; "
                        "tcp:[HOST:]PORT for TCP (host default 127.0.0.1)")
    g.add_argument("--publish-backlog", type=_number(int, "--publish-backlog", 0, 10_000_000), default=100_000,
                   metavar="N", help="frames a viewer that joins late gets first (default 100000)")


def trigger_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("triggers (sniffer/triggers: a window file around each event)")
    g.add_argument("--trigger", action="append", metavar="EXPR",
                   help="keep a window when a frame passes this filter (the TUI's language; repeatable): "
                        "fault, 'exception u:2', crc, timeout, 'write u:1 2000H', "
                        "'u:1 \"Output frequency\" > 55', 'rate(crc) > 5/min'")
    g.add_argument("--pre", metavar="TIME", help="keep this much before the trigger (default 5m)")
    g.add_argument("--post", metavar="TIME", help="and this much after its last match (default 1m)")
    g.add_argument("--ring", action="store_true", help="keep only the windows, not the whole capture")
    g.add_argument("--ring-max", metavar="SIZE", help="memory for the last --pre of the capture (default 64MiB)")
    g.add_argument("--max-window", metavar="TIME", help="a window ends at most this long after its trigger "
                   "(default 10 x --post)")
    g.add_argument("--windows", metavar="DIR", help="folder of the window files (default: that of --out, or here)")
    g.add_argument("--on-trigger", metavar="CMD", help="run CMD (sh -c) for each complete window file, with "
                   "SNIFFER_TRIGGER_FILE, _RULE, _TIME, _SUMMARY ... in its environment")
    g.add_argument("--on-trigger-timeout", metavar="TIME", help="kill --on-trigger's command after this (default 60s)")


def _device_name(text: str) -> str:
    name = text.strip()
    if not name or len(name) > 200 or not name.isprintable():
        raise argparse.ArgumentTypeError(f"--foxglove-device {text[:40]!r}: a name of 1-200 printable characters")
    return name


def foxglove_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("Foxglove (docs/foxglove.md)")
    g.add_argument("--foxglove-device", type=_device_name, metavar="NAME",
                   help="the device the MCAP names for Foxglove (its `foxglove` metadata: deviceName, which "
                        "Foxglove's agent and Edge Sites file the recording under); default: what the capture "
                        "recorded, else this host's name")


def mqtt_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("live values to MQTT / Home Assistant (sniffer/mqtt; read-only: nothing goes to the bus)")
    g.add_argument("--mqtt", metavar="URL", help="publish decoded values to this broker: mqtt://[USER[:PASS]@]HOST[:PORT]"
                   "/PREFIX, mqtts:// for TLS (a USER without :PASS takes $SNIFFER_MQTT_PASSWORD)")
    g.add_argument("--mqtt-ca", metavar="FILE", help="CA certificate (PEM) the broker's certificate is checked against "
                   "(default: the system's)")
    g.add_argument("--mqtt-cert", metavar="FILE", help="client certificate (PEM), for brokers that ask for one")
    g.add_argument("--mqtt-key", metavar="FILE", help="the client certificate's private key (PEM)")
    g.add_argument("--mqtt-interval", metavar="TIME", help="at most one value per register in this much capture time "
                   "(the newest goes out): 1s, 500ms (default: every confirmed value)")
    g.add_argument("--mqtt-changes", action="store_true", help="publish a value only when it changed")
    g.add_argument("--mqtt-ha", action="store_true",
                   help="Home Assistant MQTT discovery: each drive a device, its registers sensors")
    g.add_argument("--mqtt-ha-prefix", metavar="PREFIX",
                   help="Home Assistant's discovery prefix (default homeassistant)")
    g.add_argument("--mqtt-queue", type=_number(int, "--mqtt-queue", 1, 10_000_000), metavar="N",
                   help="messages waiting for the broker; past that they are dropped and counted (default 10000)")


def dataset_flags(p: argparse.ArgumentParser, progress: str) -> None:
    """export's and ingest's: --progress, --link, and the line and decoding flags a capture is read with."""
    p.add_argument("--progress", action="store_true", help=progress)
    add_jobs_flag(p)
    g = p.add_argument_group("fleet dataset")
    g.add_argument("--link", metavar="NAME",
                   help="the link a one-line capture is filed under (default: its port's name, e.g. ttyUSB0, "
                        "or \"default\"); a capture of several links files each under its own name")
    serial_flags(p)
    decode_flags(p)


class _ExportTo(argparse.Action):
    """`--to FORMAT`, or `--to dataset DIR` (DIR may also be given as --out); files after DIR are inputs."""

    def __call__(self, parser, namespace, values, option_string=None):
        fmt, *rest = values
        if fmt not in (*EXPORT_FORMATS, "dataset"):
            raise UsageError(f"argument --to: invalid choice: {fmt[:40]!r} (choose from "
                             f"{', '.join(EXPORT_FORMATS)}, dataset)")
        namespace.to = fmt
        if fmt == "dataset" and rest:
            namespace.dataset, rest = rest[0], rest[1:]
        elif rest:
            raise UsageError(f"--to {fmt} takes no folder: give the file as --out PATH (and the captures before --to)")
        namespace.more_files = rest


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="sniffer", description="Passive RS-485 sniffer for PLC <-> drive links (Modbus RTU).")
    p.add_argument("--version", action="version", version=f"sniffer {__version__}")
    sub = p.add_subparsers(dest="cmd", metavar="COMMAND", parser_class=_Parser)

    s = sub.add_parser("live", help="capture a serial port (read-only) and decode live; several ports: "
                                    "several links on one timeline; sigrok:DRIVER: a logic analyzer")
    port_flags(s)
    serial_flags(s)
    logic_flags(s, live=True)
    decode_flags(s)
    stream_flags(s, quiet=True)
    capture_out_flags(s, None, 0)
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI (default off a tty)")
    publish_flags(s)
    unattended_flags(s, port=True)
    trigger_flags(s)
    foxglove_flags(s)
    mqtt_flags(s)

    s = sub.add_parser("replay", help="decode a capture file (MCAP, byte CSV, Saleae CSV, pcap, sigrok .sr)")
    input_flags(s)
    add_jobs_flag(s)
    s.add_argument("--progress", action="store_true", help="progress bar on stderr (frames/s, ETA)")
    s.add_argument("--tui", action="store_true", help="browse the capture in the terminal UI")
    serial_flags(s)
    decode_flags(s)
    stream_flags(s, quiet=True)
    s.add_argument("--out", metavar="FOLDER", help="with --rotate: write the capture again as segments in FOLDER")
    unattended_flags(s)
    trigger_flags(s)
    foxglove_flags(s)
    mqtt_flags(s)

    s = sub.add_parser("decode", help="decode frames given as hex, one argument per frame (no timing: "
                                      "no latency or silence verdicts)")
    s.add_argument("hex", nargs="+", help="frame bytes in hex, e.g. 010300000002C40B; in an ASCII protocol "
                   "also ':' and the frame's characters (:010300000001FB), the characters in hex "
                   "(3A30...0D0A), or the binary frame with its LRC in hex (010300000001FB)")
    s.add_argument("--baud", type=_number(int, "baud rate", 1, MAX_BAUD), default=9600, help=argparse.SUPPRESS)
    decode_flags(s)
    stream_flags(s)

    s = sub.add_parser("simulate", help="write a simulated capture (MCAP or byte CSV by extension), or serve a "
                                        "simulated line on a pseudo-terminal (--pty)")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--out", metavar="FILE", help="FILE.mcap or FILE.csv")
    g.add_argument("--pty", metavar="PATH",
                   help="serve the line on a pseudo-terminal, linked at PATH, until stopped (Ctrl-C): what a "
                        "UART at the settings a program sets there receives (`sniffer detect PATH`, `live PATH`)")
    s.add_argument("--scenario", default="default", help=_SCENARIO_HELP)
    s.add_argument("--duration", type=float, default=None,
                   help="seconds of bus traffic (default 10; with --pty: until stopped)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--adapter", choices=["wire", "usb"], default="usb",
                   help="timestamps per byte (logic analyzer) or per USB read (default usb)")
    s.add_argument("--param", action="append", metavar="KEY=VALUE",
                   help="change the scenario: a setting (poll_period_ms=50) or a unit's (unit2.rated_current_a=7.5)")
    serial_flags(s)
    g = s.add_argument_group("receiver (--out): record what a sniffer set to other settings than the line's receives")
    g.add_argument("--receiver-baud", type=_number(int, "--receiver-baud", 50, MAX_BAUD), metavar="BAUD")
    g.add_argument("--receiver-parity", choices=["N", "E", "O"], type=str.upper)
    g.add_argument("--receiver-stopbits", type=int, choices=[1, 2])
    unattended_flags(s)
    foxglove_flags(s)

    s = sub.add_parser("demo", help="live capture of a simulated bus over a pseudo-terminal")
    s.add_argument("--scenario", default="default", help=_SCENARIO_HELP)
    s.add_argument("--seed", type=int, default=1)
    capture_out_flags(s, "demo.mcap", 15.0)
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI")
    decode_flags(s, bus=False)
    stream_flags(s, quiet=True)
    publish_flags(s)
    unattended_flags(s)
    trigger_flags(s)
    foxglove_flags(s)
    mqtt_flags(s)

    s = sub.add_parser("attach", help="view a capture that another process publishes (--publish, sniffer serve)")
    s.add_argument("socket", help="the capture's socket (or tcp:[HOST:]PORT)")
    s.add_argument("--headless", action="store_true", help="text stream instead of the TUI (default off a tty)")
    s.add_argument("--tui", action="store_true", help="the TUI even without a terminal (sniffer serve uses it)")
    s.add_argument("--exit-with-parent", action="store_true", help=argparse.SUPPRESS)  # serve's viewers
    stream_flags(s)

    s = sub.add_parser("serve", help="serve the TUI to browsers (textual-serve); the capture runs on its own")
    port_flags(s, " (or --demo)")
    s.add_argument("--demo", action="store_true", help="capture the simulated bus of `sniffer demo` instead")
    s.add_argument("--scenario", default="default", help="with --demo: the scenario (default default)")
    s.add_argument("--seed", type=int, default=1, help=argparse.SUPPRESS)
    serial_flags(s)
    decode_flags(s)
    capture_out_flags(s, None, 0)
    g = s.add_argument_group("serving")
    g.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only)")
    g.add_argument("--http-port", type=_number(int, "--http-port", 1, 65535), default=8000,
                   help="HTTP port (default 8000)")
    g.add_argument("--public-url", help="URL browsers use to reach the server (when behind a proxy or --host 0.0.0.0)")
    g.add_argument("--socket", metavar="PATH",
                   help="where the capture publishes (default: a fresh one in $XDG_RUNTIME_DIR or /tmp)")
    g.add_argument("--publish-backlog", type=_number(int, "--publish-backlog", 0, 10_000_000), default=100_000,
                   metavar="N", help="frames a viewer that joins late gets first (default 100000)")
    unattended_flags(s, port=True)
    trigger_flags(s)
    foxglove_flags(s)
    mqtt_flags(s)

    s = sub.add_parser(
        "detect", formatter_class=argparse.RawDescriptionHelpFormatter,
        help="find an unknown line's baud rate, parity, stop bits and protocol by listening (read-only)",
        description=_DETECT_HELP, epilog=_DETECT_EPILOG)
    s.add_argument("port", help="serial device, e.g. /dev/ttyUSB0; or a logic capture: a sigrok .sr file, or a live "
                                "analyzer sigrok:DRIVER (bit widths from the samples: tells 8E1 from 8E2)")
    logic_flags(s, live=True)
    s.add_argument("--bauds", action="append", metavar="RATES",
                   help="more baud rates to try, first: 250000,31250 (repeatable)")
    s.add_argument("--write-bus", metavar="FILE.toml", help="write the line's settings as a bus file for live --bus")
    s.add_argument("--max-time", type=float, default=60.0, metavar="S",
                   help="give up after S seconds of listening (default 60)")
    s.add_argument("--quiet-time", type=float, default=5.0, metavar="S",
                   help="no byte in the first S seconds: no traffic (default 5)")
    s.add_argument("--units-time", type=float, default=2.0, metavar="S",
                   help="once certain, listen S seconds more for the units and their poll periods (default 2)")
    s.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")

    s = sub.add_parser("status", help="how an unattended capture is doing: uptime, frames, errors, segments, "
                                      "disk use (its status file)")
    s.add_argument("path", nargs="?", default=".", help="the capture's folder or its status file (default: .)")
    s.add_argument("--json", action="store_true", help="print the status file as it is")

    s = sub.add_parser("repair", help="make a truncated (killed) or damaged capture readable by any MCAP reader")
    s.add_argument("file")
    s.add_argument("-o", "--out", help="output file (default: FILE.repaired.mcap)")

    s = sub.add_parser("check", help="decode a capture and compare it with its golden text (exit 0 same, 1 diff)")
    input_flags(s)
    s.add_argument("--golden", required=True, metavar="FILE.txt", help="the reviewed golden decode")
    s.add_argument("--update-golden", action="store_true", help="rewrite the golden (review the diff!)")
    s.add_argument("--time-tol-ms", type=float, default=1.0, help="frame time tolerance (default 1 ms)")
    s.add_argument("--latency-tol-ms", type=float, default=1.0, help="latency tolerance (default 1 ms)")
    add_jobs_flag(s)
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("diff", help="what changed between two captures: units, polls, registers, errors, latency")
    s.add_argument("a")
    s.add_argument("b")
    s.add_argument("--format", choices=["text", "json"], default="text", help="output format (default text)")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("learn", help="a skeleton register map (registers.toml) from a capture's traffic, to name")
    input_flags(s)
    s.add_argument("--out", required=True, metavar="FILE.toml",
                   help="the map to write; its stem is the model id (--model-file FILE.toml --device UNIT=STEM)")
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("report", help="a bus-health report of captures: one HTML file that opens offline")
    s.add_argument("captures", nargs="+", metavar="CAPTURE",
                   help="capture files (MCAP, byte CSV, Saleae CSV, pcap/pcapng) or rotated captures' folders, "
                        "reported as one, in this order")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    s.add_argument("--out", required=True, metavar="FILE.html", help="the report to write")
    s.add_argument("--compare", metavar="GOLDEN",
                   help="a reference capture: the page adds what changed against it (as `sniffer diff GOLDEN ...`)")
    s.add_argument("--title", help="the page's title (default: Bus report: the captures' names)")
    s.add_argument("--progress", action="store_true", help="a progress bar per capture on stderr")
    add_jobs_flag(s)
    serial_flags(s)
    decode_flags(s)

    s = sub.add_parser("export", help="decode a capture into csv, parquet, pcap (Wireshark), mcap or jsonl, or "
                                      "captures into a fleet dataset (--to dataset DIR)")
    s.add_argument("file", nargs="*", help="capture file: MCAP, byte CSV, Saleae CSV, pcap/pcapng (several with "
                                           "--to dataset: each is a segment of the dataset)")
    s.add_argument("--input-format", choices=INPUT_FORMATS, default="auto")
    s.add_argument("--to", required=True, nargs="+", action=_ExportTo, metavar=("FORMAT", "DIR"),
                   help=f"output format: {', '.join(EXPORT_FORMATS)}, or `dataset DIR`: a partitioned Parquet "
                        "dataset in folder DIR (made if new, else appended to; docs/fleet.md)")
    s.add_argument("--out", metavar="PATH", help="output file (csv/parquet: also PATH stem.points.*); with --to "
                                                 "dataset: the dataset folder")
    dataset_flags(s, "show a progress bar on stderr")
    logic_flags(s)
    foxglove_flags(s)

    s = sub.add_parser("ingest", help="take a folder of MCAP captures into a fleet dataset; already taken ones "
                                      "are skipped (docs/fleet.md)")
    s.add_argument("folder", help="the folder of captures (*.mcap, in subfolders too; *.part files are left out)")
    s.add_argument("--to", required=True, metavar="DIR", dest="dataset", help="the dataset folder (made if new)")
    dataset_flags(s, "show a progress bar per capture on stderr")
    add_dask_flag(s)

    s = sub.add_parser("query", help="SQL over a fleet dataset with DuckDB: views frames, points, annotations, "
                                     "captures (docs/fleet.md)")
    s.add_argument("dataset", metavar="DIR", help="the dataset folder")
    s.add_argument("sql", nargs="?", help="a query, e.g. \"SELECT link, count(*) FROM frames GROUP BY link\"")
    s.add_argument("--preset", choices=sorted(PRESETS), help="a named query instead: " + "; ".join(
        f"{name}: {p.about}" for name, p in sorted(PRESETS.items())))
    s.add_argument("--format", choices=["table", "csv", "json"], default="table",
                   help="output: an aligned table (default), CSV, or JSON (an array of objects)")
    s.add_argument("--max-rows", type=_number(int, "--max-rows", 1, 10**9), default=100,
                   help="rows a table shows (default 100; csv and json give every row)")
    s.add_argument("--show-sql", action="store_true", help="print the preset's SQL instead of running it")
    s.add_argument("--read-only", action="store_true",
                   help="for SQL from elsewhere (a dashboard, a script): the SQL may read the dataset's views "
                        "only, never open, write or attach a file, nor install an extension (without it, "
                        "DuckDB runs with your rights)")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not args.cmd:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        from sniffer.capture.settings import CaptureSpec

        spec = CaptureSpec.from_args(args)
        return command(args.cmd)(spec, args)
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # output piped into `head` etc.: stop quietly
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except Exception as e:  # noqa: BLE001 - sorted below: bad input is one line, a bug keeps its traceback
        rc = _one_line(e)
        if rc is None:
            raise
        return rc


def _one_line(e: Exception) -> int | None:
    """Print `e` as one error line and give its exit code, or None for an error that is a bug."""
    from decoders.registry import DeviceMapError
    from decoders.tables import MapError

    from sniffer.capture.busfile import BusFileError
    from sniffer.simulator.overrides import OverrideError
    from sniffer.formats.mcap.sink import CaptureStorageError

    if isinstance(e, (UsageError, CaptureError, SettingsError, DeviceMapError, BusFileError, MapError,
                      OverrideError)):
        _say(str(e))
        return EXIT_USAGE
    if isinstance(e, CaptureStorageError):
        _say(str(e))
        return EXIT_FAILED
    from sniffer.parallel.engine import WorkerError

    if isinstance(e, WorkerError):  # a part's process failed: its last line (the traceback is on stderr above)
        _say(f"--jobs: {str(e).strip().splitlines()[0]}")
        return EXIT_FAILED
    if isinstance(e, OSError):  # e.g. an output that cannot be written
        _say(f"{e.filename + ': ' if isinstance(e.filename, str) else ''}{e.strerror or e}")
        return EXIT_FAILED
    return None


def _say(text: str) -> None:
    text = " ".join(text.split())  # one line, whatever the message held
    if len(text) > 400:
        text = text[:397] + "..."
    print(f"sniffer: error: {text}", file=sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
