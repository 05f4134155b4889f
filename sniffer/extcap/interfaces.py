"""What `sniffer extcap` shows Wireshark: its interfaces, their link type and the config dialog of each.

An interface's value says what it captures (`Target.parse` reads it back when Wireshark starts a capture):

    rs485:/dev/serial/by-id/usb-FTDI_...   a serial adapter (or a port or gateway URL the launcher names)
    rs485-bus:/home/me/plant.toml          a bus file's [[links]], each link a pcapng interface
    rs485-link:/home/me/plant.toml#pump    one [[links]] table of a bus file alone (its name %-quoted: no '#')
    rs485-sigrok:fx2lafw                    a logic analyzer sigrok-cli finds
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
from dataclasses import dataclass
from urllib.parse import quote, unquote

from sniffer import __version__
from sniffer.formats.pcap.format import LINKTYPE_USER0

PORT, BUS, LINK, SIGROK = "rs485:", "rs485-bus:", "rs485-link:", "rs485-sigrok:"
BY_ID = "/dev/serial/by-id"
BAUDS = (1200, 2400, 4800, 9600, 14400, 19200, 38400, 57600, 76800, 115200, 230400, 250000)
SIGROK_SCAN_S = 8.0


@dataclass(frozen=True)
class Target:
    kind: str  # "port", "bus", "link" or "sigrok"
    what: str  # the port (path, COMn or URL), the bus file, or the sigrok driver
    link: str | None = None  # kind "link": the name of its [[links]] table in bus file `what`

    @property
    def value(self) -> str:
        if self.kind == "link":
            return f"{LINK}{self.what}#{quote(self.link or '', safe='')}"
        return {"port": PORT, "bus": BUS, "sigrok": SIGROK}[self.kind] + self.what

    @classmethod
    def parse(cls, value: str) -> "Target":
        if value.startswith(LINK):
            path, sep, name = value[len(LINK):].rpartition("#")
            if sep and path and name:
                return cls("link", path, unquote(name))
        for prefix, kind in ((BUS, "bus"), (SIGROK, "sigrok"), (PORT, "port")):
            if value.startswith(prefix) and len(value) > len(prefix):
                return cls(kind, value[len(prefix):])
        raise ValueError(f"{value!r} is not an interface of this tool "
                         "(rs485:PORT, rs485-bus:FILE, rs485-link:FILE#LINK, rs485-sigrok:DRIVER)")


def version_line() -> str:
    return f"extcap {{version={__version__}}}{{display=RS-485 sniffer (Modbus RTU, read-only)}}"


def targets(ports=(), bus_files=(), sigrok: bool = True) -> list[tuple[Target, str]]:
    """(target, display name) of everything capturable now: the launcher's own ports and bus files first."""
    out: list[tuple[Target, str]] = []
    seen: set[str] = set()
    for p in [*ports, *serial_adapters()]:
        if p not in seen:
            seen.add(p)
            out.append((Target("port", p), f"RS-485 Modbus: {os.path.basename(p) if p.startswith('/') else p}"))
    for b in bus_files:
        path = os.path.abspath(b)
        links = _links_of(path)
        names = f" ({', '.join(name for name, _ in links)})" if links else ""
        out.append((Target("bus", path), f"RS-485 Modbus: bus file {os.path.basename(path)}{names}"))
        for name, ports in links:  # and each link alone (the whole file's interface captures them all)
            out.append((Target("link", path, name), f"RS-485 Modbus: {os.path.basename(path)}: {name} "
                        f"({' + '.join(os.path.basename(p) if p.startswith('/') else p for p in ports)})"))
    if sigrok:
        for driver, text in sigrok_analyzers():
            out.append((Target("sigrok", driver), f"RS-485 Modbus: logic analyzer {text}"))
    return out


def interface_lines(found: list[tuple[Target, str]]) -> list[str]:
    return [version_line()] + [f"interface {{value={t.value}}}{{display={_clean(name)}}}" for t, name in found]


def dlt_lines() -> list[str]:
    return [f"dlt {{number={LINKTYPE_USER0}}}{{name=USER0}}{{display=Modbus RTU (user DLT 147: decode as mbrtu)}}"]


def config_lines(target: Target) -> list[str]:
    """The capture dialog: baud, parity and stop bits (`detect` by default: listened for first), a bus file;
    a logic analyzer's receive channel."""
    lines = [
        # a selector: Wireshark 4.0 has no editselector (another rate: `sniffer live PORT --format pcapng | wireshark
        # -k -i -`, docs/wireshark.md)
        "arg {number=0}{call=--line-baud}{display=Baud rate}{type=selector}"
        "{tooltip=detect: listen first and find the line's settings (read-only); or a rate}",
        "value {arg=0}{value=detect}{display=detect}{default=true}",
        *(f"value {{arg=0}}{{value={b}}}{{display={b}}}" for b in BAUDS),
        "arg {number=1}{call=--line-parity}{display=Parity}{type=selector}"
        "{tooltip=detect: found with the baud rate (or taken from the bus file)}",
        "value {arg=1}{value=detect}{display=detect}{default=true}",
        "value {arg=1}{value=N}{display=none (N)}", "value {arg=1}{value=E}{display=even (E)}",
        "value {arg=1}{value=O}{display=odd (O)}",
        "arg {number=2}{call=--line-stopbits}{display=Stop bits}{type=selector}",
        "value {arg=2}{value=detect}{display=detect}{default=true}",
        "value {arg=2}{value=1}{display=1}", "value {arg=2}{value=2}{display=2}",
        "arg {number=3}{call=--line-bus}{display=Bus file}{type=fileselect}{mustexist=true}"
        "{tooltip=a bus file (sniffer detect --write-bus): the line's settings and its drives' models; "
        "the fields above override it}",
    ]
    if target.kind == "sigrok":
        lines.append("arg {number=4}{call=--line-rx}{display=Receive channel}{type=string}{default=D0}"
                     "{tooltip=the analyzer channel on the line's receive side (A/B through a transceiver)}")
    if target.kind in ("bus", "link"):
        lines = [x for x in lines if "{arg=3}" not in x and "{number=3}" not in x]  # the interface is the bus file
    return lines


def serial_adapters() -> list[str]:
    """Serial adapters by their stable /dev/serial/by-id name; where there is none (Windows, macOS), pyserial's
    list of ports (COM5, /dev/cu.usbserial-...)."""
    named = sorted(glob.glob(os.path.join(BY_ID, "*")))
    if named or os.path.isdir(BY_ID):
        return named
    try:
        from serial.tools import list_ports

        return sorted(p.device for p in list_ports.comports())
    except Exception:  # noqa: BLE001 - no port list where pyserial cannot look: nothing to list
        return []


def sigrok_analyzers() -> list[tuple[str, str]]:
    """(driver, description) of each analyzer `sigrok-cli --scan` finds (none without sigrok-cli); its demo
    driver is left out (it is not a bus)."""
    exe = shutil.which("sigrok-cli")
    if exe is None:
        return []
    try:
        r = subprocess.run([exe, "--scan"], capture_output=True, text=True, timeout=SIGROK_SCAN_S)
    except (OSError, subprocess.TimeoutExpired):
        return []
    found = []
    for line in r.stdout.splitlines():
        driver, sep, text = line.partition(" - ")
        driver = driver.strip()
        if sep and driver and " " not in driver and driver != "demo":
            found.append((driver, f"{driver} ({text.split(':')[0].strip()})"))
    return found


def _links_of(path: str) -> list[tuple[str, tuple[str, ...]]]:
    """(name, ports) of each [[links]] table of the bus file; none where it has none or does not read."""
    try:
        from sniffer.capture.busfile import load_bus_file

        bus = load_bus_file(path)
    except Exception:  # noqa: BLE001 - a bus file that does not read is said when it is captured
        return []
    return [(link.name, tuple(link.ports)) for link in getattr(bus, "links", None) or ()]


def _clean(text: str) -> str:
    return text.replace("{", "(").replace("}", ")").replace("\n", " ")
