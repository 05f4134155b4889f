"""What the user says about a logic-analyzer capture: which channel is which, and which analyzer.

    --rx CH [--tx CH] [--de CH] [--invert] [--samplerate RATE]     (LogicSpec)
    sniffer live sigrok:DRIVER[:conn=...][:KEY=VALUE...]            (DeviceSpec)

The channels are named from the probed slave's side: `--rx` is what it
receives (with `--rx` alone: the half-duplex bus, both directions on one
channel), `--tx` what it sends (its responses), `--de` its transceiver's
driver-enable (high while it drives the bus).  `--invert`: the UART lines idle
low (probed on the RS-232 side of a converter, or through an inverting
buffer); it does not apply to `--de`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from sniffer.line import LineSettings, SettingsError
from sniffer.events import CaptureError

PREFIX = "sigrok:"
_NAME = re.compile(r"[A-Za-z0-9_.+#/\[\] -]{1,64}")  # no ':' ',' '=' (sigrok-cli's own separators)
_DRIVER = re.compile(r"[a-z0-9][a-z0-9-]{0,63}")
_OPTION = re.compile(r"[a-z_]{1,32}=[^:,\s]{1,200}")


def channel_name(text: str, flag: str) -> str:
    name = text.strip()
    if not _NAME.fullmatch(name) or name != text:
        raise SettingsError(f"{flag} {text[:40]!r}: a channel name as the analyzer or the file spells it "
                            "(letters, digits, no ':' ',' '=')")
    return name


@dataclass(frozen=True)
class LogicSpec:
    """The channels of a logic capture, and the line settings its UART decoder runs with."""

    rx: str
    tx: str | None = None
    de: str | None = None
    invert: bool = False
    samplerate: int | None = None  # live: the analyzer's rate (Hz); a file says its own
    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    databits: int | None = None

    def __post_init__(self) -> None:
        used = [c for c in (self.rx, self.tx, self.de) if c is not None]
        if len(set(used)) != len(used):
            raise SettingsError(f"--rx, --tx and --de must name different channels (given: {', '.join(used)})")

    @classmethod
    def from_args(cls, args, line) -> LogicSpec | None:
        """The spec of --rx/--tx/--de/--invert/--samplerate (None without --rx); `line` the flags' and bus file's
        LineChoice (the UART decoder needs the baud rate before the capture is read)."""
        rx = getattr(args, "rx", None)
        others = [f for f, v in (("--tx", getattr(args, "tx", None)), ("--de", getattr(args, "de", None)),
                                 ("--invert", getattr(args, "invert", False))) if v]
        if rx is None:
            if others:
                raise SettingsError(f"{others[0]} needs --rx CHANNEL (the channel the line is on)")
            return None
        rate = getattr(args, "samplerate", None)
        hz = None
        if rate is not None:
            from sniffer.sources.srzip import parse_rate

            try:
                hz = parse_rate(rate)
            except ValueError as e:
                raise SettingsError(f"--samplerate: {e}") from None
        tx, de = getattr(args, "tx", None), getattr(args, "de", None)
        return cls(channel_name(rx, "--rx"), None if tx is None else channel_name(tx, "--tx"),
                   None if de is None else channel_name(de, "--de"), bool(getattr(args, "invert", False)), hz,
                   line.baud, line.parity, line.stopbits, line.databits)

    def line(self, where: str) -> LineSettings:
        """The UART's settings (parity N and 1 stop bit unless given); CaptureError without a baud rate."""
        if self.baud is None:
            raise CaptureError(f"{where}: a logic capture is decoded at a baud rate you give: --baud (and --parity, "
                               f"--stopbits), or a --bus file; `sniffer detect {where}` measures it")
        return LineSettings(int(self.baud), (self.parity or "N").upper(), int(self.stopbits or 1),
                            int(self.databits or 8))

    @property
    def channels(self) -> tuple[str, ...]:
        return tuple(c for c in (self.rx, self.tx, self.de) if c is not None)

    def roles(self) -> dict[str, str]:
        """Wire (Chunk.channel) -> the one role its frames can have: with --tx the channel is the direction;
        bytes the slave sent under its driver-enable (`de_channel`) are responses."""
        roles: dict[str, str] = {}
        if self.tx is not None:
            roles[self.rx] = "request"
            roles[self.tx] = "response"
        if self.de is not None:
            roles[self.de_channel] = "response"
        return roles

    @property
    def de_channel(self) -> str:
        """The wire name of the bytes sent while DE was high: the slave's line (TX, else the bus) plus the DE."""
        return f"{self.tx or self.rx}+{self.de}"

    def to_dict(self) -> dict:
        return {"rx": self.rx, "tx": self.tx, "de": self.de, "invert": self.invert}


@dataclass(frozen=True)
class DeviceSpec:
    """`sigrok:DRIVER[:KEY=VALUE...]`: an analyzer sigrok-cli drives (`-d DRIVER:KEY=VALUE...`)."""

    driver: str
    options: tuple[str, ...] = ()

    @classmethod
    def parse(cls, text: str) -> DeviceSpec:
        if not text.startswith(PREFIX):
            raise SettingsError(f"{text[:60]!r} is not sigrok:DRIVER[:conn=...]")
        driver, *opts = text[len(PREFIX):].split(":")
        if not _DRIVER.fullmatch(driver):
            raise SettingsError(f"{text[:60]!r}: give sigrok:DRIVER, e.g. sigrok:fx2lafw (`sigrok-cli -L` lists them)")
        for o in opts:
            if not _OPTION.fullmatch(o):
                raise SettingsError(f"{text[:60]!r}: {o[:40]!r} is not a KEY=VALUE driver option (e.g. conn=1.5)")
        return cls(driver, tuple(opts))

    @property
    def arg(self) -> str:
        """sigrok-cli's -d argument."""
        return ":".join((self.driver, *self.options))

    def __str__(self) -> str:
        return PREFIX + self.arg


def is_device(text: str | None) -> bool:
    return bool(text) and text.startswith(PREFIX)
