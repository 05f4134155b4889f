"""What to do when a capture's line settings look wrong: the end of its warning (sniffer.analysis.linehealth).

    what_to_do(info, "")                       # a live port: run detect on it, and what detect tries first
    what_to_do(info, "", file="line3.mcap")    # a replay: capture again at what detect finds at the line

`detect` listens at its candidates in one order (candidates.py: the common rates at 8N1, most
common first; search.py: then the formats at the rate that frames): the warning names the first
of them, so the engineer knows what it will try.  A capture file of bytes cannot be set right by a
replay's flags: its bytes are what a UART at the capture's settings received (only its protocol can
be read again otherwise).  A logic analyzer's capture (a sigrok `.sr` file,
`sigrok:DRIVER`) is measured instead: detect reads the bit widths off the samples.
"""

from __future__ import annotations

from sniffer.detect.candidates import baud_order

FIRST = 4  # settings named


def first_settings(n: int = FIRST) -> list[str]:
    """The settings `sniffer detect` listens at first: `9600 8N1`, `19200 8N1`, ..."""
    return [f"{b} 8N1" for b in baud_order(())[:n]]


def _listing(items: list[str]) -> str:
    return ", ".join(items[:-1]) + f" and {items[-1]}" if len(items) > 1 else "".join(items)


def ports_of(info, link: str = "") -> list[str]:
    """The port(s) a line was read from: the link's, or the capture's ([] when none is known)."""
    if info is None:
        return []
    if link:
        d = next((x for x in info.links if x.get("name") == link), None)
        ports = d.get("ports") if d is not None else None
        if isinstance(ports, list) and all(isinstance(p, str) for p in ports):
            return list(ports)
    port = getattr(info, "port", "") or ""
    return [port] if port and not port.startswith("(") else []  # "(simulated)": no port to run detect on


def _logic(info, file: str | None) -> bool:
    if file is not None:
        from sniffer.sources.srzip import sniff

        return sniff(file)
    return info is not None and str(getattr(info, "source", "")).startswith("sigrok:")


def what_to_do(info, link: str = "", *, file: str | None = None) -> str:
    """The hint: for a line read now (`file` None), `run sniffer detect PORT (...)`; for a capture file, the
    settings to replay it with, and detect on the port it came from."""
    tries = f"{_listing(first_settings())} first"
    ports = ports_of(info, link)
    if _logic(info, file):
        where = file if file is not None else " ".join(ports) or "sigrok:DRIVER"
        return f"run sniffer detect {where} (it measures the bits on the wire: baud rate, parity, stop bits)"
    if file is None:
        where = " ".join(ports) or "PORT"
        return f"run sniffer detect {where} (it listens, sending nothing, at {tries})"
    at = f"sniffer detect {' '.join(ports)}" if ports else "sniffer detect PORT"
    return (f"sniffer detect listens to a port, not a file, and a file holds what a UART at its settings received: "
            f"capture again at the settings detect finds at the line ({at}; it tries {tries}), or replay with "
            f"another --protocol if the settings were right")
