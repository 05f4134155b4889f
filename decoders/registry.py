"""Choose a decoder per unit: `--device UNIT=MODEL` (repeatable) or a bus file.

A registry is an explicit instance: built from the decoders it may use and
the device map, then passed to the pipeline.  Nothing is registered at import.
It also holds what a part of a capture carries into the next (decoders/carry.py):
`carried()` says it, `carry_in()` and `preset()` (a bus file's [parameters]) start
a registry with it, `version()` says when it changed.
"""

from __future__ import annotations

import functools

from sniffer import codes as core_codes
from sniffer.codes import MODEL_GUESS as GUESS
from sniffer.codes import MODEL_GUESS_WITHDRAWN as WITHDRAWN
from sniffer.codes import CodeBook, note
from sniffer.frame import Frame
from sniffer.protocols import PROTOCOLS

from .base import Decoder, UnitState


class DeviceMapError(ValueError):
    pass


class ParameterError(DeviceMapError):
    """A unit's known parameter (a bus file's [parameters]) that its model cannot take."""


def _same_family(a: str, b: str) -> bool:
    return a.split("-hf")[0] == b.split("-hf")[0]


class DecoderRegistry:
    def __init__(self, decoders: dict[str, Decoder], devices: dict[int, str] | None = None,
                 default: str = "generic", identify: bool = True) -> None:
        self.decoders = dict(decoders)
        if default not in self.decoders:
            raise DeviceMapError(f"default model {default!r} is not available")
        self.default = default
        self.devices: dict[int, str] = {}
        for unit, model in (devices or {}).items():
            if model not in self.decoders:
                from sniffer.stderr import did_you_mean

                known = ", ".join(sorted(self.decoders))
                raise DeviceMapError(f"unknown model {model!r} for unit {unit} (known: {known})"
                                     f"{did_you_mean(model, self.decoders)}")
            self.devices[int(unit)] = model
        self.states: dict[int, UnitState] = {}
        # unit -> (model, decoder.decode, state) once nothing can change the unit's model
        self._routes: dict[int, tuple] = {}
        self.guesses: dict[int, tuple[str, float, str]] = {}  # unit -> (model, confidence, evidence)
        self._contradicted: set[int] = set()
        self._version = 0  # changes of the guesses (UnitState.version counts the rest: version())
        self._tracking: dict | None = None  # the reads of a part decoded ahead (track())
        self._observed: list | None = None  # and the frames it observed
        self.identifier = None
        if identify:
            from .identify import Identifier

            maps = {}
            for mid, d in self.decoders.items():
                m = getattr(d, "map", None)
                if m is not None and all(m.path != o.path for o in maps.values()):
                    maps[mid] = m
            self.identifier = Identifier(maps) if maps else None
        from sniffer.protocols import all_codes

        self.codebook = CodeBook(all_codes(), *(d.codes for d in self.decoders.values()))

    def model_for(self, unit: int | None) -> str:
        """A user's map wins; else the identifier's guess; else the default (generic).

        Unit 0 (broadcast) is every unit's: the model given for unit 0 (`--device 0=M`, a bus
        file's `broadcast = "M"`), else the one model all known units share (given or
        guessed), so the manual's broadcast rules and names apply; else the default.
        """
        if unit is None:
            return self.default
        m = self.devices.get(unit)
        if m is not None:
            return m
        if unit == 0:
            models = {m for u, m in self.devices.items() if u}
            models.update(g[0] for u, g in self.guesses.items() if u not in self.devices)
            return models.pop() if len(models) == 1 else self.default
        g = self.guesses.get(unit)
        return g[0] if g else self.default

    def _identify(self, f: Frame) -> None:
        if self.identifier is None:
            return
        if self._observed is not None:  # a part decoded ahead: what it observed, to observe again (replay)
            from .identify import Seen

            n0 = len(f.annotations)
            self._verdict(f)
            self._observed.append(("seen", Seen(f), tuple(f.annotations[n0:])))
            return
        self._verdict(f)

    def _verdict(self, f) -> None:
        got = self.identifier.observe(f)
        if got is None:
            return
        model, conf, evidence = got
        given = self.devices.get(f.unit)
        self._version += 1
        if model is None:  # an earlier guess withdrawn
            was = self.guesses.pop(f.unit, None)
            if was is not None and given is None:
                f.annotations.append(note(WITHDRAWN, f"unit {f.unit} is generic again, {evidence}", 0, len(f.raw)))
        elif given is None:
            self.guesses[f.unit] = got
            f.annotations.append(note(GUESS, f"unit {f.unit} looks like {model}: {evidence}", 0, len(f.raw)))
        elif given != model and f.unit not in self._contradicted and not _same_family(given, model):
            self._contradicted.add(f.unit)
            why = self.identifier.ruled_out(f.unit, given)
            f.annotations.append(note(core_codes.MODEL_MISMATCH,
                                      f"unit {f.unit} is mapped to {given} but looks like {model}: {evidence}"
                                      + (f"; and {why}" if why else ""), 0, len(f.raw)))

    # ---- what a part of a capture carries into the next (decoders/carry.py) ------------------
    def version(self) -> int:
        """A number that changes whenever `carried()` may have (cheap: asked after every frame)."""
        return self._version + sum(st.version for st in self.states.values())

    def carried(self) -> dict:
        """{unit: {"model", "confidence", "holding", "extra"}} of the units with something to carry."""
        out: dict[str, dict] = {}
        for unit in sorted(set(self.states) | set(self.guesses)):
            d: dict = {}
            g = self.guesses.get(unit)
            if g is not None and unit not in self.devices:
                d["model"], d["confidence"] = g[0], g[1]
            st = self.states.get(unit)
            dec = self.decoders.get(self.model_for(unit))
            if st is not None and hasattr(dec, "carried"):
                d.update(dec.carried(st))
            if d:
                out[str(unit)] = d
        return out

    def carry_in(self, units: dict) -> None:
        """Start from what a part of the capture before knew (`carried()` of that registry); a model the
        user's map gives for a unit wins over the one carried.  Bad entries are skipped: metadata is input."""
        if self._observed is not None:
            self._observed.append(("carry", units))
        for key, d in (units or {}).items():
            try:
                unit = int(key)
            except (TypeError, ValueError):
                continue
            if not isinstance(d, dict) or not 0 <= unit <= 255:
                continue
            model = d.get("model")
            if isinstance(model, str) and model in self.decoders and unit not in self.devices:
                conf = d.get("confidence")
                conf = float(conf) if isinstance(conf, (int, float)) and not isinstance(conf, bool) else 0.5
                self.guesses[unit] = (model, conf, "carried over from the part of the capture before")
                if self.identifier is not None:
                    self.identifier.seed(unit, model, conf)
                self._version += 1
            st = self.state(unit)
            for addr, raw in (d.get("holding") or {}).items():
                if str(addr).isdigit() and isinstance(raw, int) and not isinstance(raw, bool) and 0 <= raw <= 0xFFFF:
                    st.holding[int(addr)] = raw
                    st.version += 1
            for k, v in (d.get("extra") or {}).items():
                if isinstance(v, (str, int, float, bool)):
                    st.remember(str(k), v)
            self._routes.pop(unit, None)

    # ---- a part decoded ahead of the parts before it (sniffer.parallel) ----------------------------
    # A part of a capture can be decoded in another process before the parts before it are: it starts
    # from a guess of what the registry knows at its cut (`restore`), records every read of a unit's
    # memory it has not written itself and every frame the identifier observed (`track`), and is kept
    # only if the guess was right where it mattered: the same `naming()` at the cut, every read equal to
    # the true value, and every observed frame noted the same from the true state (`replay`).
    def snapshot(self) -> dict:
        """Everything the registry learnt from the traffic, as plain data (`restore` takes it)."""
        return {"states": {u: st.dump() for u, st in self.states.items()}, **self.identity_state()}

    def identity_state(self) -> dict:
        """What names the units (the guesses, the contradicted maps, the identifier's evidence)."""
        return {"guesses": dict(self.guesses), "contradicted": sorted(self._contradicted),
                "identifier": self.identifier.snapshot() if self.identifier is not None else None}

    def restore(self, snap: dict) -> None:
        """Start from `snapshot()` (or `identity_state()` and "states" from elsewhere) of a registry."""
        self._tracking = self._observed = None
        self.states = {}
        for unit, d in (snap.get("states") or {}).items():
            self.state(unit).load(d)
        self.guesses = dict(snap["guesses"])
        self._contradicted = set(snap["contradicted"])
        if self.identifier is not None and snap.get("identifier") is not None:
            self.identifier.restore(snap["identifier"])
        self._routes.clear()

    def naming(self) -> tuple:
        """What routes a frame to its model now, beside the identifier's evidence: the guesses and the maps
        a guess contradicted."""
        from .identify import canonical

        return canonical(self.guesses), tuple(sorted(self._contradicted))

    def track(self) -> None:
        """Record from now on every read of a unit's memory not written since (UnitState.track), and every
        frame the identifier observes, with the notes it gave (`replay` observes them again)."""
        self._tracking = {}
        self._observed = []
        for st in self.states.values():
            st.track(self._tracking)

    def tracked(self) -> tuple[dict, dict, list]:
        """(reads, writes, observed) since `track()`: {(unit, table, key): (known, value)},
        {unit: UnitState.written()}, [("seen", Seen, notes) or ("carry", units)]."""
        writes = {u: w for u, st in self.states.items() if (w := st.written())}
        return dict(self._tracking or {}), writes, list(self._observed or ())

    def replay(self, observed: list) -> str | None:
        """Observe again, in order, what a part decoded ahead observed (`tracked`); None if every frame got
        the same notes here, else why not (this registry then holds what it learnt up to there)."""
        for entry in observed:
            if entry[0] == "carry":
                self.carry_in(entry[1])
                continue
            _, seen, notes = entry
            seen.annotations = []
            self._verdict(seen)
            if tuple(seen.annotations) != notes:
                return f"unit {seen.unit} named otherwise than the part guessed"
        return None

    def preset(self, params: dict[int, dict]) -> None:
        """A bus file's [parameters]: per unit, values the bus may never show (`{1: {"Cn-02": 60}}`), put in
        the unit's shadow through its model (the one the user's map gives); DeviceMapError (one line)."""
        for unit, values in sorted((params or {}).items()):
            model = self.devices.get(unit)
            dec = self.decoders.get(model) if model is not None else None
            if dec is None or not hasattr(dec, "preset"):
                why = (f"give its model (--device {unit}=MODEL, or the bus file's [units]): its parameters are "
                       f"named by that model's manual" if dec is None else f"model {model} has no register map")
                raise ParameterError(f"parameters of unit {unit}: {why}")
            try:
                dec.preset(self.state(unit), dict(values))
            except ValueError as e:
                raise ParameterError(f"parameters of unit {unit}: {e}") from None

    def state(self, unit: int) -> UnitState:
        st = self.states.get(unit)
        if st is None:
            st = self.states[unit] = UnitState(unit)
            if self._tracking is not None:
                st.track(self._tracking)
        return st

    def decode(self, f: Frame) -> None:
        unit = f.unit
        if unit is None or f.protocol == "noise":
            return
        route = self._routes.get(unit)
        if route is None:
            route = self._route(f)
        model, decode, state = route
        f.model = model
        n0 = len(f.annotations)
        try:
            decode(f, f.peer, state)
            if f.protocol in _TEXT:
                _spans_to_text(f, n0)
        except Exception as e:  # a decoder bug must not stop a capture
            f.annotations.append(
                note(core_codes.DECODE_SHORT, f"decoder {model} failed: {type(e).__name__}: {e}",
                     0, len(f.raw))
            )

    def _route(self, f: Frame) -> tuple:
        """Identify (while the unit's verdict can still change) and pick the decoder; cache when final."""
        unit = f.unit
        self._identify(f)
        model = self.model_for(unit)
        route = (model, self.decoders[model].decode, self.state(unit))
        if self.identifier is None or self.identifier.settled(unit):
            self._routes[unit] = route
        return route

_TEXT = {name: p for name, p in PROTOCOLS.items() if p.text}


def _spans_to_text(f: Frame, n0: int) -> None:
    """Decoder spans count ADU bytes: on a text (ASCII) frame, map them onto its characters.

    The annotations the decoder added (from `n0` on) and every point's span; a point gets a
    new span list (the decoders share theirs between frames).
    """
    span = _TEXT[f.protocol].raw_span
    n = len(f.raw)
    for k in range(n0, len(f.annotations)):
        a = f.annotations[k]
        f.annotations[k] = type(a)(a.code, a.severity, a.detail, *span(a.start, a.end, n))
    for p in f.points:
        s = p.get("span")
        if s is not None:
            p["span"] = list(span(s[0], s[1], n))


def parse_device_args(items: list[str] | None) -> dict[int, str]:
    """['1=a510', '2=tds-v8'] -> {1: 'a510', 2: 'tds-v8'}."""
    out: dict[int, str] = {}
    for item in items or []:
        unit_s, sep, model = item.partition("=")
        try:
            unit = int(unit_s, 0)
        except ValueError:
            unit = -1
        if not sep or not model or not 0 <= unit <= 255:
            raise DeviceMapError(f"--device {item!r}: expected UNIT=MODEL with UNIT 0..255")
        out[unit] = model.strip()
    return out


def builtin_decoders() -> dict[str, Decoder]:
    """Every model that ships with the sniffer, by --device model id.

    Decoders keep no per-unit state (that lives in the registry's UnitStates),
    so the loaded maps are shared by every registry of the process.
    """
    return dict(_builtin_decoders())


def _shipped() -> tuple[tuple[type, tuple], ...]:
    """The decoder classes that ship, each with the loaders of the models it serves (in --device order).

    One table: `builtin_decoders` loads the models from it, `code_book` reads each class's declared
    `codes` from it without loading a map.
    """
    from .generic import GenericModbus
    from .table_decoder import TableDecoder
    from . import pd_series, synplus_spl, tds_v8, teco_a510

    return (
        (GenericModbus, (GenericModbus,)),
        (tds_v8.TdsV8Decoder, (tds_v8.load,)),
        (teco_a510.A510Decoder, (teco_a510.load, teco_a510.load_high_frequency)),
        (TableDecoder, (synplus_spl.load,)),  # and every user map (--model-file)
        (pd_series.PdSeriesDecoder, (pd_series.load,)),
    )


@functools.lru_cache(maxsize=1)
def _builtin_decoders() -> dict[str, Decoder]:
    decoders: dict[str, Decoder] = {}
    for _cls, loaders in _shipped():
        for load in loaders:
            d = load()
            decoders[d.model] = d
    return decoders


def plugin_decoders() -> dict[str, Decoder]:
    """The installed plugins' models (sniffer.plugins: the `rs485_sniffer.models` entry points, and each
    `rs485_sniffer.protocols` plugin's decoder), by --device id.  A map that does not load, or an id a shipped
    model or another plugin has, is one warning line naming the plugin; the rest are kept."""
    return {model: d for model, (d, _) in plugin_models().items()}


@functools.lru_cache(maxsize=1)
def plugin_models() -> dict[str, tuple[Decoder, object]]:
    """{model id: (its decoder, the sniffer.plugins.Plugin it came from)} of `plugin_decoders`."""
    from sniffer.plugins.entry import warn
    from sniffer.plugins.models import model_plugins
    from sniffer.plugins.protocols import protocol_plugins

    from .mapformats import load_model_file
    from .table_decoder import TableDecoder
    from .tables import MapError

    plugins = (*model_plugins(), *protocol_plugins())
    if not plugins:  # the usual case: no shipped map is loaded only to compare ids (every command's start-up)
        return {}
    shipped = _builtin_decoders()
    found: dict[str, tuple[Decoder, object]] = {}
    for plugin in plugins:
        obj = getattr(plugin.obj, "decoder", plugin.obj)
        if isinstance(obj, str):  # a register map's path
            try:
                made = [TableDecoder(m) for m in load_model_file(obj)]
            except (MapError, DeviceMapError, OSError, ValueError) as e:
                warn(plugin.group, plugin.name, plugin.value, plugin.dist, f"its register map does not load: {e}")
                continue
        else:
            made = [obj]
        for d in made:
            if d.model in shipped or d.model in found:
                whose = "a shipped model's" if d.model in shipped else "another plugin's"
                warn(plugin.group, plugin.name, plugin.value, plugin.dist, f"model id {d.model!r} is {whose}")
                continue
            found[d.model] = (d, plugin)
    return found


@functools.lru_cache(maxsize=1)
def code_book() -> CodeBook:
    """Every code the shipped stages may emit: the core ones, each protocol's framer's, each decoder class's
    (user maps are TableDecoders: theirs are among them), assembled from their declarations.  What a view
    that reads records (no decoder at hand) asks a code's category of.  Loads no map."""
    from sniffer.protocols import all_codes

    return CodeBook(all_codes(), *(cls.codes for cls, _ in _shipped()), *(d.codes for d in plugin_decoders().values()))


def default_registry(devices: dict[int, str] | None = None, model_files: list[str] | None = None,
                     default: str = "generic", map_base: str | None = None) -> DecoderRegistry:
    """Built-in models plus user register maps (--model-file: TOML, CSV or Home Assistant YAML,
    decoders.mapformats; a user map wins over a built-in id).  `map_base`: --map-base, how a CSV
    map counts its addresses."""
    from .mapformats import load_model_file
    from decoders.table_decoder import TableDecoder

    decoders = builtin_decoders()
    decoders.update(plugin_decoders())
    for path in model_files or []:
        for m in load_model_file(path, map_base):
            if m.model_id == "generic":  # every unit without a model falls back to it
                from .tables import MapError

                raise MapError(f"{path}: model id 'generic' is the fallback for every unit; give the map its own id")
            d = TableDecoder(m)
            decoders[d.model] = d
    return DecoderRegistry(decoders, devices, default=default)
