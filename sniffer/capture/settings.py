"""What the user asked for, and what a capture runs with: one precedence rule for every command.

A setting can come from four places; the first that says it wins:
flags > bus file > the capture's own metadata > defaults (`layered`).  Device
maps and per-unit timeouts merge unit by unit by the same rule.  `CaptureSpec`
holds the flags and the bus file (built once, in cli.py, by `from_args`; a
capture started as a process of its own, under the TUI or `serve`, gets it
whole: `encode`, `decode`);
`resolve(info)` adds what the capture says and the defaults and checks the
result (baud known, a protocol we speak, models that speak it), giving
`Resolved`: line settings, protocol, device map, timeouts, the units' known
parameters (a bus file's [parameters]), and a fresh decoder registry that
starts with what the capture's part before knew (decoders/carry.py).
sniffer.capture.session runs a capture with it.

Several links (`live P1 P2 ...`, `--tap A B`, a bus file's [[links]]): each is
a `LinkPlan` (name, ports, its own table of the bus file) and resolves on its
own, one layer more: flags > the link's table > the bus file's [serial] and
[units] (every link's defaults) > what the capture recorded for that link >
defaults (`resolve_link`).  Flags apply to every link.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from sniffer import protocols
from sniffer.events import CaptureInfo
from sniffer.line import LineSettings, SettingsError
from sniffer.mqtt.options import MqttSpec
from sniffer.capture.pairer import DEFAULT_TIMEOUT_MS
from sniffer.capture.pipeline import Pipeline, roles_of
from sniffer.formats import STREAM_FORMATS
from sniffer.formats.mcap.segments import Keep, Rotate
from sniffer.sources.logic_options import LogicSpec
from sniffer.triggers.options import TriggerSpec

MAX_TIMEOUT_MS = 86_400_000.0  # a day: anything longer is a typo, not a response timeout
MAX_DURATION_S = 366 * 86_400.0


def finite(value, what: str, *, upper: float) -> float:
    """A number that must be finite, >= 0 and <= upper (flags, bus files): SettingsError otherwise."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SettingsError(f"{what} {str(value)[:60]!r} is not a number") from None
    if not math.isfinite(v) or v < 0 or v > upper:
        raise SettingsError(f"{what} {str(value)[:60]} must be a finite number from 0 to {upper:.0f}")
    return v


@dataclass(frozen=True)
class LineChoice:
    """What one place says about the line (flags, a bus file, a capture, the defaults); None = nothing."""

    baud: int | None = None
    parity: str | None = None
    stopbits: int | None = None
    databits: int | None = None
    protocol: str | None = None
    devices: Mapping[int, str] = field(default_factory=dict)
    timeout_ms: float | None = None
    unit_timeouts: Mapping[int, float] = field(default_factory=dict)
    params: Mapping[int, Mapping[str, object]] = field(default_factory=dict)  # unit -> {"Cn-02": 60}

    @classmethod
    def from_info(cls, info: CaptureInfo | None) -> LineChoice:
        if info is None:
            return cls()
        return cls(info.baud, info.parity, info.stopbits, info.databits, info.protocol, dict(info.devices or {}))

    @classmethod
    def from_link(cls, link: dict | None) -> LineChoice:
        """What a capture recorded for one of its links (CaptureInfo.links)."""
        if not link:
            return cls()
        return cls(link.get("baud"), link.get("parity"), link.get("stopbits"), link.get("databits"),
                   link.get("protocol"), {int(u): m for u, m in (link.get("devices") or {}).items()},
                   link.get("timeout_ms"), {int(u): ms for u, ms in (link.get("unit_timeouts") or {}).items()})

    @classmethod
    def from_bus(cls, bus) -> LineChoice:
        if bus is None:
            return cls()
        return cls(bus.baud, bus.parity, bus.stopbits, bus.databits, bus.protocol, dict(bus.devices),
                   None, dict(bus.timeouts_ms), {u: dict(p) for u, p in bus.params.items()})


DEFAULTS = LineChoice(parity="N", stopbits=1, databits=8, protocol=protocols.DEFAULT, timeout_ms=DEFAULT_TIMEOUT_MS)


def layered(*layers: LineChoice) -> LineChoice:
    """The one precedence rule: the first layer that says a thing wins; maps merge unit by unit (a unit's
    parameters one by one)."""
    def first(name):
        return next((getattr(x, name) for x in layers if getattr(x, name) is not None), None)

    devices: dict[int, str] = {}
    timeouts: dict[int, float] = {}
    params: dict[int, dict] = {}
    for x in reversed(layers):
        devices.update(x.devices)
        timeouts.update(x.unit_timeouts)
        for unit, values in x.params.items():
            params.setdefault(unit, {}).update(values)
    return LineChoice(first("baud"), first("parity"), first("stopbits"), first("databits"), first("protocol"),
                      devices, first("timeout_ms"), timeouts, params)


@dataclass(frozen=True)
class Resolved:
    """The settings a capture runs with, checked."""

    line: LineSettings
    protocol: protocols.Protocol
    devices: dict[int, str]
    model_files: tuple[str, ...]
    timeout_ms: float
    unit_timeouts: dict[int, float]
    map_base: str | None = None  # --map-base: how CSV model files count their addresses
    params: dict[int, dict] = field(default_factory=dict)  # the units' known parameters (bus file [parameters])

    def registry(self, carried: dict | None = None):
        """A fresh decoder registry (decoders keep per-unit state: one per pipeline), starting with what
        `carried` says the part of the capture before knew (decoders/carry.py), then the known parameters."""
        from decoders.registry import default_registry

        registry = default_registry(self.devices, list(self.model_files) or None,
                                    default=self.protocol.default_model, map_base=self.map_base)
        if carried:
            registry.carry_in(carried)
        registry.preset(self.params)
        return registry

    def pipeline(self, info: CaptureInfo, sinks, registry=None) -> Pipeline:
        from decoders.carry import of_info

        return Pipeline(info, self.line, registry or self.registry(of_info(info)), sinks, protocol=self.protocol.name,
                        timeout_ms=self.timeout_ms, unit_timeouts=self.unit_timeouts or None,
                        directions=roles_of(info))

    def record_in(self, info: CaptureInfo) -> None:
        """The settings used travel with the capture (an MCAP written from it replays without flags;
        its register maps are attached from the model files named here: decoders.mapfile)."""
        info.baud, info.parity, info.stopbits = self.line.baud, self.line.parity, self.line.stopbits
        info.databits = self.line.databits
        info.protocol = self.protocol.name
        info.devices = dict(self.devices)
        for key in ("model_files", "map_base"):
            info.extra.pop(key, None)  # a replay says what it decoded with, not what the capture was
        if self.model_files:
            info.extra["model_files"] = [os.path.abspath(p) for p in self.model_files]
            if self.map_base is not None:
                info.extra["map_base"] = self.map_base

    def record_link(self, link: dict) -> None:
        """The settings one link of several ran with, into its CaptureInfo.links entry (replay re-splits
        each link with them)."""
        link.update(baud=self.line.baud, parity=self.line.parity, stopbits=self.line.stopbits,
                    databits=self.line.databits, protocol=self.protocol.name,
                    devices={str(u): m for u, m in sorted(self.devices.items())}, timeout_ms=self.timeout_ms,
                    unit_timeouts={str(u): ms for u, ms in sorted(self.unit_timeouts.items())})

    def describe(self) -> str:
        models = ", ".join(f"{u}={m}" for u, m in sorted(self.devices.items()))
        return f"{self.line.label()} {self.protocol.name}" + (f" ({models})" if models else "")


MASTER, SLAVES = "master", "slaves"  # the wires of a tapped 4-wire link (Chunk.channel)


@dataclass(frozen=True)
class LinkPlan:
    """One link of several: its name, its port (two with --tap: the master's pair, the slaves' pair),
    and what its own [[links]] table of the bus file says."""

    name: str
    ports: tuple[str, ...]
    tap: bool = False
    choice: LineChoice = LineChoice()

    @property
    def channels(self) -> tuple[str, ...]:
        return (MASTER, SLAVES) if self.tap else ("",)

    def entry(self) -> dict:
        """Its CaptureInfo.links entry before the settings are added (Resolved.record_link)."""
        return {"name": self.name, "ports": list(self.ports), "tap": self.tap, "channels": list(self.channels)}


def link_plans(ports=(), taps=(), bus=None) -> tuple[LinkPlan, ...]:
    """The links of `live P1 P2 ... --tap A B`, or of the bus file's [[links]]: () for one plain port.

    A link is named for its port's file name (ttyUSB0; a tap: ttyUSB1+ttyUSB2), or its path where
    two names would clash; a bus file's links have the names it gives them."""
    import os

    if bus is not None and bus.links:
        if ports or taps:
            raise SettingsError(f"{bus.path}: has [[links]]: give no ports on the command line (or no [[links]])")
        return tuple(LinkPlan(b.name, b.ports, b.tap, LineChoice.from_bus(b)) for b in bus.links)
    groups = [((p,), False) for p in ports] + [(tuple(t), True) for t in taps]
    if len(groups) < 2 and not taps:
        return ()
    names = ["+".join(os.path.basename(p.rstrip("/")) or p for p in g) for g, _ in groups]
    names = [n if names.count(n) == 1 else "+".join(g) for n, (g, _) in zip(names, groups)]
    seen = [p for g, _ in groups for p in g]
    for p in seen:
        if seen.count(p) > 1:
            raise SettingsError(f"{p}: given twice (one port is one link, or one wire of a --tap)")
    return tuple(LinkPlan(n, g, tap) for n, (g, tap) in zip(names, groups))


def only_links(plans: tuple[LinkPlan, ...], names, bus) -> tuple[LinkPlan, ...]:
    """The bus file's links named by `live --only-link` (all of them without it): one link of a bus file,
    with its own table's settings, captured alone (Wireshark's interface of one link)."""
    if not names:
        return plans
    if bus is None or not bus.links:
        raise SettingsError("--only-link picks [[links]] of a --bus file: give a --bus file with [[links]]")
    known = [p.name for p in plans]
    for name in names:
        if name not in known:
            raise SettingsError(f"{bus.path}: no [[links]] named {name!r} (it has: {', '.join(known)})")
    return tuple(p for p in plans if p.name in names)


@dataclass(frozen=True)
class CaptureSpec:
    """What the user asked for, in one object: built once from the flags and the bus file.

    `flags` and `bus` are the two top layers of the precedence rule; the capture's
    metadata and DEFAULTS are added by `resolve`.  The rest says where the capture
    comes from (port, input file, simulated scenario) and where it goes.
    """

    flags: LineChoice = LineChoice()
    bus_file: str | None = None
    bus: LineChoice = LineChoice()
    model_files: tuple[str, ...] = ()
    map_base: str | None = None  # --map-base 0|1|modicon for CSV model files (None: what the file says, else 0)
    # where the capture comes from
    port: str | None = None
    links: tuple[LinkPlan, ...] = ()  # several links (or a --tap) instead of one port
    input: str | None = None  # the capture file (the first, when several)
    inputs: tuple[str, ...] = ()  # several files, a rotated capture's folder or its index (replay, check,
    # export; export --to dataset: each file a segment of the dataset)
    input_format: str = "auto"
    scenario: str | None = None
    faults: tuple[str, ...] = ()  # demo --fault KIND[:UNIT]: causes put on the simulated line (simulator.faults)
    seed: int = 1
    duration_s: float = 0.0
    # where it goes
    out: str | None = None  # the MCAP file a live capture or demo writes (None: none)
    stream: str | None = "text"  # frames on stdout: "text", "jsonl", "pcapng" or None (quiet)
    headless: bool = False
    publish: str | None = None
    publish_backlog: int = 100_000
    # unattended (sniffer.formats.mcap.segments, sniffer.capture.status)
    rotate: Rotate | None = None  # --rotate: the MCAP as segments in the folder --out names
    keep: Keep | None = None  # --keep: retention of closed segments
    status: str | None = None  # --status FILE (default with --rotate: status.json in the capture's folder)
    wait_port: bool = False  # --wait-port: a port that is not there yet is waited for
    trigger: TriggerSpec | None = None  # --trigger and its flags: windows around events (sniffer.triggers)
    foxglove_device: str | None = None  # --foxglove-device: the device its MCAP names for Foxglove
    mqtt: MqttSpec | None = None  # --mqtt URL and its flags: decoded values to a broker (sniffer.mqtt)
    logic: LogicSpec | None = None  # --rx/--tx/--de...: a logic analyzer's channels (sigrok .sr, live sigrok:DRIVER)

    @classmethod
    def of(cls, *, baud=None, parity=None, stopbits=None, protocol=None, devices=None, timeout_ms=None,
           unit_timeouts=None, model_files=(), bus_file: str | None = None, **kw) -> CaptureSpec:
        """A spec from keyword arguments (the pytest plugin, tests): they are the flags layer."""
        flags = LineChoice(baud, parity.upper() if parity else None, stopbits, None, protocol,
                           {int(u): str(m) for u, m in (devices or {}).items()}, timeout_ms,
                           dict(unit_timeouts or {}))
        bus = _bus_file(bus_file)
        links = kw.pop("links", None) or link_plans(bus=bus)
        return cls(flags=flags, bus_file=bus_file, bus=LineChoice.from_bus(bus), model_files=tuple(model_files),
                   links=links, **kw)

    @classmethod
    def from_args(cls, args) -> CaptureSpec:
        """The spec for parsed command-line flags (any subset: each command has the flags it needs)."""
        from decoders.registry import parse_device_args

        def opt(name, default=None):
            return getattr(args, name, default)

        timeout = opt("timeout_ms")
        flags = LineChoice(opt("baud"), opt("parity"), opt("stopbits"), None, opt("protocol"),
                           parse_device_args(opt("device")),
                           None if timeout is None else finite(timeout, "--timeout-ms", upper=MAX_TIMEOUT_MS))
        duration = opt("duration", 0.0) or 0.0
        fmt = opt("format", "text")
        files = opt("file")
        files = list(files) if isinstance(files, (list, tuple)) else [files] if files else []
        rotate, keep = Rotate.parse(opt("rotate")), Keep.parse(opt("keep"))
        if keep is not None and rotate is None:
            raise SettingsError("--keep needs --rotate (it deletes a rotated capture's oldest segments)")
        if rotate is not None and opt("no_out"):
            raise SettingsError("--rotate writes the capture's MCAP as segments: not with --no-out")
        trigger = TriggerSpec.from_args(args)
        if rotate is not None and trigger is not None and trigger.ring:
            raise SettingsError("--ring keeps only the trigger windows, --rotate the whole capture as segments: "
                                "give one of them")
        bus_file = _bus_file(opt("bus"))
        logic = LogicSpec.from_args(args, layered(flags, LineChoice.from_bus(bus_file)))
        ports = list(opt("ports") or ())
        links = only_links(link_plans(ports, opt("tap") or (), bus_file), opt("only_link") or (), bus_file)
        port = opt("port") or (ports[0] if ports else None)
        if links:
            port = links[0].ports[0]
        return cls(
            flags=flags, bus_file=opt("bus"), bus=LineChoice.from_bus(bus_file),
            model_files=tuple(opt("model_file") or ()),
            map_base=opt("map_base"),
            port=port, links=links, input=files[0] if files else None, inputs=tuple(files),
            input_format=opt("input_format", "auto") or "auto",
            scenario=opt("scenario"), seed=opt("seed", 1) or 1, faults=tuple(opt("fault") or ()),
            duration_s=finite(duration, "--duration", upper=MAX_DURATION_S),
            out=None if opt("no_out") else opt("out"),
            stream=None if opt("quiet") else (fmt if fmt in STREAM_FORMATS else STREAM_FORMATS[0]),
            headless=bool(opt("headless")), publish=opt("publish"),
            publish_backlog=opt("publish_backlog", 100_000), trigger=trigger, mqtt=MqttSpec.from_args(args),
            rotate=rotate, keep=keep, status=opt("status"), wait_port=bool(opt("wait_port")),
            foxglove_device=opt("foxglove_device"), logic=logic,
        )

    def read_paths(self) -> list[str]:
        """Every file (or folder, or port) the command reads: its capture files, ports, bus file and model
        files -- what none of its outputs may be (sniffer.formats.outputs)."""
        ports = [p for plan in self.links for p in plan.ports] or ([self.port] if self.port else [])
        files = list(self.inputs) or ([self.input] if self.input else [])
        return [p for p in (*files, *ports, self.bus_file, *self.model_files) if p]

    def with_(self, **changes) -> CaptureSpec:
        return replace(self, **changes)

    def resolve(self, info: CaptureInfo | None = None, *, need_baud: bool = True) -> Resolved:
        """flags > bus file > `info` (the capture's metadata) > defaults, checked; SettingsError otherwise."""
        c = layered(self.flags, self.bus, LineChoice.from_info(info), DEFAULTS)
        where = f"{info.source or 'the capture'}" if info is not None else "the line"
        return self._checked(c, where, need_baud)

    def resolve_link(self, name: str, info: CaptureInfo | None = None, *, need_baud: bool = True) -> Resolved:
        """One link of several: flags > its [[links]] table > the bus file > what `info` recorded for it
        > the capture's line settings > defaults."""
        plan = next((p for p in self.links if p.name == name), None)
        recorded = next((x for x in (info.links if info is not None else ()) if x.get("name") == name), None)
        # the capture's own line fields come last (its first link's): its line settings, not its units
        line_only = replace(LineChoice.from_info(info), devices={}) if info is not None else LineChoice()
        c = layered(self.flags, plan.choice if plan else LineChoice(), self.bus, LineChoice.from_link(recorded),
                    line_only, DEFAULTS)
        return self._checked(c, f"link {name}", need_baud)

    def _checked(self, c: LineChoice, where: str, need_baud: bool) -> Resolved:
        if c.baud is None:
            if need_baud:
                raise SettingsError(f"{where} does not say its baud rate: give --baud (and --parity/--stopbits)")
            c = replace(c, baud=9600)
        line = LineSettings(_int(c.baud, "baud rate"), str(c.parity).upper(), _int(c.stopbits, "stop bits"),
                            _int(c.databits, "data bits"))
        protocol = protocols.get(c.protocol)
        timeouts = {int(u): finite(ms, f"timeout of unit {u}", upper=MAX_TIMEOUT_MS)
                    for u, ms in c.unit_timeouts.items()}
        resolved = Resolved(line, protocol, dict(c.devices), self.model_files,
                            finite(c.timeout_ms, "response timeout", upper=MAX_TIMEOUT_MS), timeouts, self.map_base,
                            {int(u): dict(p) for u, p in c.params.items() if p})
        from decoders.registry import ParameterError

        try:  # unknown models, bad model files and parameters fail here, before anything opens
            registry = resolved.registry()
        except ParameterError as e:
            raise ParameterError(f"{self.bus_file}: {e}" if self.bus_file else str(e)) from None
        for unit, model in sorted(resolved.devices.items()):
            fam = getattr(registry.decoders[model], "family", "pd" if model == "pd-series" else "modbus")
            if fam != protocol.family:
                speaks = ", ".join(n for n, p in protocols.known().items() if p.family == fam)
                raise SettingsError(f"unit {unit}: model {model} speaks {speaks}, not {protocol.name} "
                                    f"(give --protocol, or another model)")
        return resolved

    def encode(self) -> bytes:
        """The whole spec as one JSON document: what a capture started as a process of its own gets (on its
        stdin, so a password in it never shows in the process list); `decode` gives it back equal."""
        import msgspec

        return msgspec.json.encode(self)

    @classmethod
    def decode(cls, data: bytes) -> CaptureSpec:
        import msgspec

        try:
            return msgspec.json.decode(data, type=cls)
        except msgspec.DecodeError as e:  # not what `encode` wrote: another version's, or cut short
            raise SettingsError(f"the capture's settings did not arrive whole: {e}") from None


def _int(v, what: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise SettingsError(f"{what} {str(v)[:60]!r} is not a whole number")
    try:
        return int(v)
    except ValueError:
        raise SettingsError(f"{what} {str(v)[:60]!r} is not a whole number") from None


def _bus_file(path: str | None):
    if not path:
        return None
    from sniffer.capture.busfile import load_bus_file

    return load_bus_file(path)
