"""What a source hands the pipeline: timestamped bytes, silence ticks, gaps.

Time is integer nanoseconds on the capture's monotonic clock.  A Chunk says
where its time came from:

* per byte (`byte_t_ns` given): a logic analyzer, a sigrok CSV or the
  simulator knows the start-bit time of every byte;
* per read (`byte_t_ns` is None): a USB adapter only tells us when a read
  returned, and one read may hold several frames or part of one.  `t_ns` is
  then the host time the read returned, *after* its last byte arrived.
"""

from __future__ import annotations

from dataclasses import dataclass, field

FLAG_FRAMING = "framing"
FLAG_PARITY = "parity"
# a part of a capture's metadata (CaptureInfo.extra): {link: the request that waited for its answer where the
# part was cut} (capture.pairer.Pairer.waiting), so the part read alone pairs that answer as the whole capture does
WAITING_KEY = "waiting_requests"


@dataclass(slots=True, frozen=True)
class Chunk:
    """Bytes from one read (or one logic-analyzer run of bytes)."""

    t_ns: int
    data: bytes
    byte_t_ns: tuple[int, ...] | None = None
    flags: tuple[tuple[int, str], ...] = ()  # (offset in data, FLAG_*)
    channel: str = ""  # which wire of one link (two receive-only adapters on a 4-wire link: --tap)
    link: str = ""  # which link of a multi-link capture ("" when there is one line)
    # per read, from a live reader that stalled (lost its CPU or waited for the interpreter for several
    # ticks): the port was last seen empty this long before t_ns, so the bytes came within it, and a long
    # gap before the read is not proven silence.  None: the reader looked every tick (or a file, an older
    # capture)
    unseen_ns: int | None = None
    # a logic analyzer's driver-enable line (--de): the bytes were sent while the slave's driver was enabled,
    # from `de[0]` to `de[1]` (ns; None: before the capture began / not known yet).  None: no DE window
    de: tuple[int | None, int | None] | None = None
    # one packet of a capturing tool (pcap): the tool drew its edges, so no frame spans them (the framer
    # takes both as HARD boundaries, whatever the times say)
    packet: bool = False

    @property
    def per_byte(self) -> bool:
        return self.byte_t_ns is not None


def read_fields(c: Chunk) -> tuple:
    """A read as it crosses a pipe to a helper process: the Chunk's fields in order (Chunk(*read_fields(c)) ==
    c), since pickling the dataclass itself costs ten times as much."""
    return (c.t_ns, c.data, c.byte_t_ns, c.flags, c.channel, c.link, c.unseen_ns, c.de, c.packet)


@dataclass(slots=True, frozen=True)
class Tick:
    """The source saw no byte up to `t_ns`: lets the framer close frames on silence.

    Live capture records the ticks that changed anything, so a replay makes
    the same decisions at the same places.
    """

    t_ns: int
    link: str = ""


@dataclass(slots=True, frozen=True)
class Gap:
    """The source was interrupted (adapter unplugged, port lost) from t_ns to t_end_ns.

    `state`: what the decoders knew where the input goes on (a replayed folder's segment after a
    missing one: its recorded decoder state, decoders/carry.py), {link: {unit: ...}}; None: nothing.
    """

    t_ns: int
    t_end_ns: int
    reason: str
    link: str = ""
    state: dict | None = field(default=None, compare=False)


Event = Chunk | Tick | Gap


# How a capture's (and each frame's) times were taken: per byte (a logic analyzer, the simulator), per read
# of a local adapter, per read of a network connection to a gateway (sources/pyserial_line.py), or not at all
TIME_SOURCES = ("byte", "read", "net", "none")
PER_READ = ("read", "net")  # times of a read of several bytes: a frame's start is estimated back from it


@dataclass(slots=True)
class CaptureInfo:
    """Metadata of a capture: written to MCAP, read back on replay."""

    source: str = ""
    port: str = ""
    baud: int | None = None
    parity: str | None = None  # "N", "E", "O"
    stopbits: int | None = None
    databits: int = 8
    time_source: str = "byte"  # one of TIME_SOURCES
    t0_ns: int = 0  # capture start on the monotonic clock; JSONL `t` counts from here
    wall_anchor_ns: int = 0  # wall-clock ns (Unix epoch) at t0_ns
    low_latency: dict = field(default_factory=dict)
    devices: dict = field(default_factory=dict)  # unit -> model id
    protocol: str = "modbus-rtu"
    sniffer_version: str = ""
    extra: dict = field(default_factory=dict)
    # several links on one timeline (sniffer.capture.links): one dict per link, in order: name, ports,
    # channels, and the settings it was captured with (baud ... devices); empty for one line
    links: list = field(default_factory=list)

    def to_dict(self) -> dict:
        d = {
            "source": self.source,
            "port": self.port,
            "baud": self.baud,
            "parity": self.parity,
            "stopbits": self.stopbits,
            "databits": self.databits,
            "time_source": self.time_source,
            "t0_ns": self.t0_ns,
            "wall_anchor_ns": self.wall_anchor_ns,
            "low_latency": dict(self.low_latency),
            "devices": {str(k): v for k, v in self.devices.items()},
            "protocol": self.protocol,
            "sniffer_version": self.sniffer_version,
            "extra": dict(self.extra),
        }
        if self.links:  # only then: a one-line capture's metadata is as it always was
            d["links"] = [dict(link) for link in self.links]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "CaptureInfo":
        info = cls()
        for key in (
            "source", "port", "baud", "parity", "stopbits", "databits", "time_source",
            "t0_ns", "wall_anchor_ns", "low_latency", "protocol", "sniffer_version", "extra",
        ):
            if key in d and d[key] is not None:
                setattr(info, key, d[key])
        info.devices = {int(k): v for k, v in (d.get("devices") or {}).items()}
        links = d.get("links")
        info.links = [dict(x) for x in links if isinstance(x, dict)] if isinstance(links, list) else []
        return info


class CaptureError(Exception):
    """A capture file that cannot be read: one clear line for the user, exit code 2."""
