"""The command line's parts: the parser, its value types, and every flag group (each declared once).

A command module declares its own parser with `command_parser` and the groups it takes
(`serial_flags(p)`, `decode_flags(p)` ...); a flag several commands take lives in one group
here, so its name, type, default and help are written once.  Every option's default is shown
in its help (HelpFormatter), and every command's help ends with its examples.
"""

from __future__ import annotations

import argparse
import re
import textwrap

MAX_BAUD = 4_000_000
MAX_DURATION_S = 366 * 86_400.0  # a year and a day: anything longer is a typo
DAY_S = 86_400.0


class UsageError(Exception):
    """A wrong flag or a combination that cannot work: one line, exit code 2."""


class Once(argparse.Action):
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


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions and examples as written (command_parser wraps the prose); every option's default shown."""

    def _get_help_string(self, action):
        text = action.help or ""
        d = action.default
        if SAYS_DEFAULT.search(text) or d is None or d is False or d == [] or d is argparse.SUPPRESS:
            return text
        if not action.option_strings and action.nargs in ("*", "?"):
            return text
        return f"{text} (default: %(default)s)" if text else "default: %(default)s"


def help_text(action: argparse.Action, prog: str) -> str:
    """An option's help as --help shows it (its default added, %(default)s and the like filled in)."""
    text = HelpFormatter(prog)._get_help_string(action)
    params = {k: v for k, v in dict(vars(action), prog=prog).items() if v is not argparse.SUPPRESS}
    if params.get("choices") is not None:
        params["choices"] = ", ".join(map(str, params["choices"]))
    return text % params


SAYS_DEFAULT = re.compile(r"\(default\b|\bdefault:|\bdefault with\b", re.I)  # a help that says its default


class Parser(argparse.ArgumentParser):
    def __init__(self, *a, **kw) -> None:
        kw.setdefault("formatter_class", HelpFormatter)
        super().__init__(*a, **kw)
        self.register("action", None, Once)  # every single-value flag, in every subcommand
        self.register("action", "store", Once)

    def parse_known_args(self, args=None, namespace=None):
        ns, rest = super().parse_known_args(args, namespace)
        ns.__dict__.pop("_given_once", None)
        return ns, self._late_positionals(ns, rest)

    def _late_positionals(self, ns, rest: list[str]) -> list[str]:
        """argparse matches positionals in runs between flags: in `query DIR --read-only "SQL"` the optional SQL
        is matched (empty) with DIR and "SQL" is left over.  A left-over word fills the optional positionals
        still empty, in order, so flags may stand anywhere."""
        for action in self._actions:
            if not rest or rest[0].startswith("-"):
                break
            if action.option_strings or action.nargs != "?" or getattr(ns, action.dest, None) != action.default:
                continue
            try:
                action(self, ns, self._get_values(action, [rest.pop(0)]))
            except argparse.ArgumentError as e:
                self.error(str(e))
        return rest

    def parse_args(self, args=None, namespace=None):
        ns, rest = self.parse_known_args(args, namespace)
        if rest:  # argparse's own message, with the command's flag a mistyped one is closest to
            self.error(f"unrecognized arguments: {' '.join(rest)}{self._closest_flag(ns, rest)}")
        return ns

    def _closest_flag(self, ns, rest: list[str]) -> str:
        from sniffer.stderr import did_you_mean

        flags = list(self._option_string_actions)
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction) and getattr(ns, action.dest, None) in action.choices:
                flags += list(action.choices[getattr(ns, action.dest)]._option_string_actions)
        for word in rest:
            if word.startswith("--"):
                name = word.partition("=")[0]
                if name in _ELSEWHERE and name not in flags:
                    return "; " + _ELSEWHERE[name]
                hint = did_you_mean(name, [f for f in flags if f.startswith("--")])
                if hint:
                    return hint
        return ""

    def error(self, message: str):  # one line, not usage + line
        m = _INVALID_CHOICE.search(message)
        if m:  # a mistyped command or choice: the closest one
            from sniffer.stderr import did_you_mean

            message += did_you_mean(m.group(1), re.findall(r"'([^']*)'", m.group(2)))
        raise UsageError(message)


# flags people try that the tool has in another form: where it is (a spelling-near flag would mislead)
_ELSEWHERE = {
    "--filter": "frames are filtered in the TUI (/ and the filter language, docs/filters.md) and by `sniffer query`; "
                "--trigger EXPR keeps a window around each frame that passes one",
    "--where": "frames are filtered in the TUI (/, docs/filters.md) and by `sniffer query`",
}
_INVALID_CHOICE = re.compile(r"invalid choice: '([^']*)' \(choose from (.*)\)$")


WIDTH = 78


def prose(text: str) -> str:
    """Paragraphs (blank-line separated) filled to WIDTH; lines indented by two spaces are kept as they are."""
    out = []
    for para in textwrap.dedent(text).strip("\n").split("\n\n"):
        lines = para.splitlines()
        kept = any(x.startswith("  ") for x in lines)
        out.append(para if kept else textwrap.fill(" ".join(lines), WIDTH, break_on_hyphens=False))
    return "\n\n".join(out)


def command_parser(subparsers, name: str, *, help: str, examples: list[str], description: str = "",
                   epilog: str = "") -> argparse.ArgumentParser:
    """The parser of command `name`: its one-line `help` (the command list), a `description` (default: the
    help), and the `examples` its --help ends with (`sniffer ...` lines, each with an optional `  # why`)."""
    lines = "\n".join(f"  {e}" for e in examples)
    tail = (prose(epilog) + "\n\n" if epilog else "") + f"examples:\n{lines}"
    p = subparsers.add_parser(name, help=help, description=prose(description or help[:1].upper() + help[1:] + "."),
                              epilog=tail, formatter_class=HelpFormatter)
    p.summary, p.examples = help, list(examples)  # the man page and the help test read them
    return p


# ---------------------------------------------------------------- value types
def number(kind, what: str, lo, hi):
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


def duration(flag: str, *, bare: str = "s", unit: str = "s", upper_s: float = MAX_DURATION_S):
    """The type of a flag that takes a time: 90s, 1.5min, 5m, 2h, 1d, 300ms, 20us (filterlang.values's one time
    grammar); a bare number keeps the flag's own unit (`bare`).  The value is a float in `unit` ("s" or "ms")."""
    scale = {"s": 1e9, "ms": 1e6}[unit]

    def parse(text: str) -> float:
        from sniffer.filterlang.values import BadValue, parse_duration

        shown = repr(text[:40])
        try:
            ns = parse_duration(text.strip(), bare)
        except BadValue as e:
            why = str(e) if "unit" in str(e) else f"not a time (e.g. 90s, 5m, 2h, 1d; a bare number is {_UNIT[bare]})"
            raise UsageError(f"{flag} {shown}: {why}") from None
        if not 0 <= ns <= upper_s * 1e9:
            raise UsageError(f"{flag} {shown}: from 0 to {_span(upper_s)}")
        return ns / scale

    parse.__name__ = "duration"
    return parse


_UNIT = {"s": "seconds", "ms": "milliseconds"}


def _span(s: float) -> str:
    for unit, n in (("d", DAY_S), ("h", 3600.0), ("min", 60.0)):
        if s >= n and s % n == 0:
            return f"{s / n:g}{unit}"
    return f"{s:g}s"


def device_name(text: str) -> str:
    name = text.strip()
    if not name or len(name) > 200 or not name.isprintable():
        raise argparse.ArgumentTypeError(f"--foxglove-device {text[:40]!r}: a name of 1-200 printable characters")
    return name


# ---------------------------------------------------------------- flag groups (each declared once)
SCENARIO_NAMES = ("default", "errors", "fast", "stress", "tds-v8", "a510", "a510-ascii", "spl", "spl-ascii",
                  "pd-series", "pd-series-ascii")  # sniffer.simulator.scenario's (a test holds them equal): that
# package takes a quarter of a second to import, every command's parser would pay it


def scenario_help() -> str:
    return f"the simulated line: {', '.join(SCENARIO_NAMES)}"


def scenario_flags(p, *, seed: bool = True, what: str = "") -> None:
    p.add_argument("--scenario", default="default", help=scenario_help() + what)
    p.add_argument("--seed", type=int, default=1,
                   help="the simulation's random seed: the same seed, the same traffic" if seed else argparse.SUPPRESS)


def jobs_flag(p) -> None:
    from sniffer.parallel.options import add_jobs_flag

    add_jobs_flag(p)


def fault_flag(p, what: str) -> None:
    p.add_argument("--fault", action="append", metavar="KIND[:UNIT][@FROM-TO][,SEVERITY]", help=what)


def port_flags(p, what: str = "") -> None:
    p.add_argument("ports", nargs="*", metavar="PORT",
                   help=f"serial device, e.g. /dev/ttyUSB0{what}; several: one link each, captured together "
                        "(one clock, one MCAP, a link column); or a --bus file's [[links]]")
    p.add_argument("--tap", nargs=2, action="append", metavar=("PORT_A", "PORT_B"),
                   help="one 4-wire link tapped by two receive-only adapters: the master's pair (requests) "
                        "on PORT_A, the slaves' pair (responses) on PORT_B, merged by time (repeatable)")


_DEFAULTS_FROM = {  # where --baud, --parity and --stopbits default from
    "live": ("the --bus file's, else 9600", "the --bus file's, else N", "the --bus file's, else 1"),
    "file": ("the --bus file's, else what the capture recorded (a byte CSV records none)",
             "the --bus file's, else what the capture recorded, else N",
             "the --bus file's, else what the capture recorded, else 1"),
    "sim": ("the scenario's",) * 3,
}


def serial_flags(p, source: str) -> None:
    """--baud/--parity/--stopbits; `source` says where their defaults come from: "live" (a port), "file" (a
    capture: its metadata) or "sim" (the simulated scenario)."""
    baud, parity, stopbits = _DEFAULTS_FROM[source]
    g = p.add_argument_group("serial line")
    g.add_argument("--baud", type=number(int, "baud rate", 1, MAX_BAUD),
                   help=f"baud rate, e.g. 9600, 19200, 115200 (default: {baud})")
    g.add_argument("--parity", choices=["N", "E", "O"], type=str.upper, help=f"parity (default: {parity})")
    g.add_argument("--stopbits", type=int, choices=[1, 2], help=f"stop bits (default: {stopbits})")


def logic_flags(p, live: bool = False) -> None:
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


_DECODE_DEFAULTS = {  # where --device, --protocol and --timeout-ms default from, by what the command reads
    "live": ("the --bus file's units, else each unit's model as its traffic tells", "the --bus file's, else "
             "modbus-rtu", "the --bus file's, else {} ms"),
    "file": ("the --bus file's units, else what the capture recorded, else each unit's model as its traffic "
             "tells", "the --bus file's, else what the capture says, else modbus-rtu", "the --bus file's, else {} ms"),
    "sim": ("the scenario's drives", "the scenario's", "{} ms"),
    "frames": ("the --bus file's units, else each unit's model as its frames tell", "the --bus file's, else "
               "modbus-rtu", "the --bus file's, else {} ms"),
}


def decode_flags(p, source: str) -> None:
    """--device, --bus, --timeout-ms, --model-file, --map-base, --protocol; `source`: what the command reads
    ("live" a port, "file" a capture, "sim" a simulated bus, "frames" frames typed in), which says where their
    defaults come from (and whether a bus file applies)."""
    from sniffer.capture.pairer import DEFAULT_TIMEOUT_MS
    from sniffer.capture.settings import MAX_TIMEOUT_MS
    from sniffer.protocols import names

    protocols = names()

    device, protocol, timeout = _DECODE_DEFAULTS[source]
    g = p.add_argument_group("decoding")
    g.add_argument("--device", action="append", metavar="UNIT=MODEL",
                   help=f"decode UNIT with MODEL (repeatable), e.g. --device 2=a510 (default: {device})")
    if source != "sim":
        g.add_argument("--bus", metavar="FILE", help="bus file (TOML): serial settings, unit models, timeouts")
    g.add_argument("--timeout-ms", type=duration("--timeout-ms", bare="ms", unit="ms", upper_s=MAX_TIMEOUT_MS / 1e3),
                   metavar="TIME", help=f"response timeout per unit, in ms or with a unit (250, 1.5s) (default: "
                                        f"{timeout.format(f'{DEFAULT_TIMEOUT_MS:.0f}')})")
    g.add_argument("--model-file", action="append", metavar="FILE",
                   help="a device's register map: TOML (docs/register-map-format.md), CSV or Home Assistant "
                        "modbus YAML; its model id (the file's stem unless it names one) becomes a model")
    g.add_argument("--map-base", choices=["0", "1", "modicon"], default=None,
                   help="how a CSV map counts its addresses: from 0, from 1, or Modicon 4xxxx/3xxxx (default: what "
                        "the file says, else 0)")
    g.add_argument("--protocol", choices=protocols, default=None, help=f"line protocol (default: {protocol})")


def input_format_flag(p) -> None:
    from sniffer.sources.files import FORMATS as INPUT_FORMATS

    p.add_argument("--input-format", choices=INPUT_FORMATS, default="auto",
                   help="the capture files' format (auto: from the name and the first bytes)")


def input_flags(p) -> None:
    p.add_argument("file", nargs="+", help="capture file: MCAP, byte CSV, Saleae CSV, pcap/pcapng, a sigrok .sr "
                                          "(with --rx); several files, a rotated capture's folder or its "
                                          "index.json are read as one capture")
    input_format_flag(p)
    logic_flags(p)


def stream_flags(p, quiet: str = "") -> None:
    """--format text|jsonl of the frames on stdout; `quiet`: the help of --quiet (what is still written)."""
    from sniffer.formats import STREAM_FORMATS

    p.add_argument("--format", choices=STREAM_FORMATS, default=STREAM_FORMATS[0], help="the frames on stdout: one "
                   "line each (text), one JSON object each (jsonl), or a pcapng stream for Wireshark (`| wireshark -k "
                   "-i -`: Modbus RTU packets, each with a comment of the registers, CRC, pair and latency)")
    if quiet:
        p.add_argument("--quiet", action="store_true", help=f"no frame lines on stdout ({quiet})")


def progress_flag(p, what: str = "a progress bar on stderr (frames/s, ETA)") -> None:
    p.add_argument("--progress", action="store_true", help=what)


def headless_flag(p, what: str = "text stream instead of the TUI (default: the TUI on a terminal)") -> None:
    p.add_argument("--headless", action="store_true", help=what)


def capture_duration_flag(p, what: str, default: float | None = None) -> None:
    p.add_argument("--duration", type=duration("--duration"), default=default, metavar="TIME", help=what)


def capture_out_flags(p, default_out: str | None, duration_s: float, *, named: str = "sniffer-<time>.mcap") -> None:
    """--out, --no-out, --duration of a capture; without `default_out` the file is `named` when the capture starts."""
    g = p.add_argument_group("capture")
    g.add_argument("--out", default=default_out, metavar="FILE.mcap",
                   help="MCAP file to write" + ("" if default_out else f" (default: {named})"))
    g.add_argument("--no-out", action="store_true", help="do not write an MCAP file")
    capture_duration_flag(g, f"stop after this long: 90 (seconds), 10min, 8h, 1d (default: "
                             f"{f'{duration_s:g} s' if duration_s else '0: until Ctrl-C'})", duration_s)


def unattended_flags(p, port: bool = False) -> None:
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


def backlog_flag(g) -> None:
    g.add_argument("--publish-backlog", type=number(int, "--publish-backlog", 0, 10_000_000), default=100_000,
                   metavar="N", help="frames a viewer that joins late gets first")


def publish_flags(p) -> None:
    g = p.add_argument_group("viewers in other processes")
    g.add_argument("--publish", metavar="SOCKET",
                   help="publish the frames on a Unix socket (mode 0600) for `sniffer attach SOCKET`; "
                        "tcp:[HOST:]PORT for TCP (host default 127.0.0.1)")
    backlog_flag(g)


def child_flag(p) -> None:
    """The capture process's own flag (processes/capture.py): its whole CaptureSpec comes on stdin."""
    p.add_argument("--spec-from-stdin", action="store_true", help=argparse.SUPPRESS)


def trigger_flags(p) -> None:
    g = p.add_argument_group("triggers (sniffer/triggers: a window file around each event)")
    g.add_argument("--trigger", action="append", metavar="EXPR",
                   help="keep a window when a frame passes this filter (the TUI's language; repeatable): "
                        "fault, 'exception u:2', crc, timeout, 'write u:1 2000H', "
                        "'u:1 \"Output frequency\" > 55', 'rate(crc) > 5/min'")
    g.add_argument("--pre", type=duration("--pre", upper_s=DAY_S), metavar="TIME",
                   help="keep this much before the trigger (default 5m)")
    g.add_argument("--post", type=duration("--post", upper_s=DAY_S), metavar="TIME",
                   help="and this much after its last match (default 1m)")
    g.add_argument("--ring", action="store_true", help="keep only the windows, not the whole capture")
    g.add_argument("--ring-max", metavar="SIZE", help="memory for the last --pre of the capture (default 64MiB)")
    g.add_argument("--max-window", type=duration("--max-window", upper_s=DAY_S), metavar="TIME",
                   help="a window ends at most this long after its trigger (default 10 x --post)")
    g.add_argument("--windows", metavar="DIR", help="folder of the window files (default: that of --out, or here)")
    g.add_argument("--on-trigger", metavar="CMD", help="run CMD (sh -c) for each complete window file, with "
                   "SNIFFER_TRIGGER_FILE, _RULE, _TIME, _SUMMARY ... in its environment")
    g.add_argument("--on-trigger-timeout", type=duration("--on-trigger-timeout", upper_s=DAY_S), metavar="TIME",
                   help="kill --on-trigger's command after this (default 60s)")


def foxglove_flags(p) -> None:
    g = p.add_argument_group("Foxglove (docs/foxglove.md)")
    g.add_argument("--foxglove-device", type=device_name, metavar="NAME",
                   help="the device the MCAP names for Foxglove (its `foxglove` metadata: deviceName, which "
                        "Foxglove's agent and Edge Sites file the recording under); default: what the capture "
                        "recorded, else this host's name")


def mqtt_flags(p) -> None:
    g = p.add_argument_group("live values to MQTT / Home Assistant (sniffer/mqtt; read-only: nothing goes to the bus)")
    g.add_argument("--mqtt", metavar="URL", help="publish decoded values to this broker: mqtt://[USER[:PASS]@]HOST[:PORT]"
                   "/PREFIX, mqtts:// for TLS (a USER without :PASS takes $SNIFFER_MQTT_PASSWORD)")
    g.add_argument("--mqtt-ca", metavar="FILE", help="CA certificate (PEM) the broker's certificate is checked against "
                   "(default: the system's)")
    g.add_argument("--mqtt-cert", metavar="FILE", help="client certificate (PEM), for brokers that ask for one")
    g.add_argument("--mqtt-key", metavar="FILE", help="the client certificate's private key (PEM)")
    g.add_argument("--mqtt-interval", type=duration("--mqtt-interval", upper_s=DAY_S), metavar="TIME",
                   help="at most one value per register in this much capture time (the newest goes out): 1s, 500ms "
                        "(default: every confirmed value)")
    g.add_argument("--mqtt-changes", action="store_true", help="publish a value only when it changed")
    g.add_argument("--mqtt-ha", action="store_true",
                   help="Home Assistant MQTT discovery: each drive a device, its registers sensors")
    g.add_argument("--mqtt-ha-prefix", metavar="PREFIX",
                   help="Home Assistant's discovery prefix (default homeassistant)")
    g.add_argument("--mqtt-queue", type=number(int, "--mqtt-queue", 1, 10_000_000), metavar="N",
                   help="messages waiting for the broker; past that they are dropped and counted (default 10000)")


def dataset_flags(p, progress: str) -> None:
    """export's and ingest's: --progress, --link, and the line and decoding flags a capture is read with."""
    progress_flag(p, progress)
    jobs_flag(p)
    g = p.add_argument_group("fleet dataset")
    g.add_argument("--link", metavar="NAME",
                   help="the link a one-line capture is filed under (default: its port's name, e.g. ttyUSB0, "
                        "or \"default\"); a capture of several links files each under its own name")
    serial_flags(p, "file")
    decode_flags(p, "file")

