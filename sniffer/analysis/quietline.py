"""A live line that gives no byte at all: said once on stderr within seconds, with what to check.

A UART at the wrong settings still receives bytes (wrong ones: linehealth.py says so); no byte at all
means nothing reaches the adapter: not on the bus, A and B not connected (or the adapter's own
terminals), or a master that is not polling.  Silence is judged by capture time (`advance`, every
event the source gives, its idle ticks included), per link: one link of several can be the silent one.
"""

from __future__ import annotations

from collections.abc import Callable

from sniffer.events import Chunk
from sniffer.sinks.base import Sink

QUIET_S = 5.0  # as `detect --quiet-time`: no byte this long after the start is no traffic


def quiet_text(port: str, seconds: float) -> str:
    return (f"no traffic on {port}: nothing received in {seconds:.0f} s (is the adapter on the bus, A and B "
            f"connected, the line polled?); still listening. Once bytes come, `sniffer detect {port}` finds the "
            f"line's settings")


class QuietLine(Sink):
    def __init__(self, say: Callable[[str], None], quiet_s: float = QUIET_S) -> None:
        self.say = say
        self.quiet_ns = int(quiet_s * 1e9)
        self.info = None
        self.t0: int | None = None
        self.heard: set[str] = set()  # links that gave a byte
        self.said: set[str] = set()  # links said silent
        self.links: list[str] = [""]

    def start(self, info) -> None:
        self.info = info
        names = [d.get("name") for d in getattr(info, "links", None) or [] if isinstance(d, dict)]
        self.links = [n for n in names if isinstance(n, str)] or [""]

    def raw(self, ev) -> None:
        if type(ev) is Chunk and ev.data:
            link = ev.link or ""
            if link not in self.heard:
                self.heard.add(link)
                if link in self.said:
                    self.say(f"note: {self._port(link)}: traffic at last, "
                             f"{(ev.t_ns - self.t0) / 1e9:.0f} s after the start")

    def advance(self, t_ns: int) -> None:
        if self.t0 is None:
            self.t0 = t_ns
            return
        if t_ns - self.t0 < self.quiet_ns or len(self.said) == len(self.links):
            return
        for link in self.links:
            if link not in self.heard and link not in self.said:
                self.said.add(link)
                self.say("warning: " + quiet_text(self._port(link), (t_ns - self.t0) / 1e9))

    def _port(self, link: str) -> str:
        info = self.info
        d = next((x for x in getattr(info, "links", None) or [] if x.get("name") == link), None) if link else None
        ports = d.get("ports") if d is not None else [getattr(info, "port", "") or ""]
        where = " + ".join(p for p in ports or () if isinstance(p, str) and p) or "the line"
        return f"{where} ({link})" if link else where
