"""What `sniffer detect` tries: baud rates, character formats, protocols.

The formats are those field devices offer: 8 data bits with parity N, E or O and
1 stop bit, or no parity and 2 stop bits; Modbus ASCII lines often run 7 data bits
(7E1, 7O1, 7N2), which are tried when the line looks like ASCII text.  Every
format is tried with every protocol (sniffer.protocols): one listen at a baud rate
and format gives the bytes, and each protocol's framer reads them.
"""

from __future__ import annotations

from sniffer.line import LineSettings, SettingsError

# the common rates, most common first (the order they are tried in)
COMMON_BAUDS = (9600, 19200, 38400, 115200, 57600, 4800, 2400, 1200, 14400, 230400, 460800, 921600)
FORMATS_8 = ("8N1", "8E1", "8O1", "8N2")
FORMATS_7 = ("7E1", "7O1", "7N2")
LISTENED = frozenset(FORMATS_8 + FORMATS_7)
# the same format with the other number of stop bits: a receiver takes both alike (a UART checks the first
# stop bit only), so only the characters' spacing tells them apart.  8E2, 8O2, 7E2, 7O2 and 7N1 are never
# listened at (a listen at the twin receives the same bytes): a listen at their twin reports them
TWINS = {f"{d}{p}{s}": f"{d}{p}{3 - s}" for d in "87" for p in "NEO" for s in (1, 2)}
MIN_BAUD, MAX_BAUD = 300, 4_000_000


def setting(baud: int, fmt: str) -> LineSettings:
    """LineSettings for a baud rate and a format such as "8E1"."""
    return LineSettings(baud, fmt[1], int(fmt[2]), int(fmt[0]))


def fmt_of(line: LineSettings) -> str:
    return f"{line.databits}{line.parity}{line.stopbits}"


def parse_bauds(texts: list[str] | None) -> tuple[int, ...]:
    """--bauds 250000,31250 (repeatable): extra rates, tried first; SettingsError for a bad one."""
    out: list[int] = []
    for text in texts or ():
        for part in text.replace(" ", ",").split(","):
            if not part:
                continue
            try:
                baud = int(part)
            except ValueError:
                raise SettingsError(f"--bauds: {part[:40]!r} is not a whole number") from None
            if not MIN_BAUD <= baud <= MAX_BAUD:
                raise SettingsError(f"--bauds: {baud} is outside {MIN_BAUD}..{MAX_BAUD}")
            if baud not in out:
                out.append(baud)
    return tuple(out)


def baud_order(extra: tuple[int, ...]) -> tuple[int, ...]:
    """The rates in the order they are tried: the ones asked for, then the common ones."""
    return extra + tuple(b for b in COMMON_BAUDS if b not in extra)
