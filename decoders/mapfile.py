"""A model's tables as one file a capture can carry (an MCAP attachment): decodable without the sniffer.

    map_file("a510")                               # ("a510.registers.toml", "application/toml", b"...")
    map_file("pump", model_files=("pump.csv",))    # a --model-file map, as registers.toml
    map_file("generic")                            # None: registers by number, no table

A table model is written in the register-map format of docs/register-map-format.md (what
`--model-file` loads): a map kept as TOML (the built-ins' registers.toml, a user's TOML) is carried
as its file, comments and every row's manual note included; a map read from CSV or Home Assistant
YAML as the TOML `decoders.mapformats.to_toml` writes from it (addresses 0-based, as decoded).  A
few comment lines go first: the model, where the map came from, and what a decoder adds to the
table (`map_note`: the A510's 0.1 Hz rule of `a510-hf`).  The PD-series protocol's tables
(decoders/pd_series/schema.py: parameters, status selectors, control and status bits, functions,
error replies) are JSON.
"""

from __future__ import annotations

import functools
import os

import msgspec

TOML = "application/toml"
JSON = "application/json"


def model_decoder(model: str, model_files=(), map_base: str | None = None):
    """The decoder of `model`: a --model-file map first (as decoders.registry.default_registry), then
    the built-ins; None for a model neither knows (or a model file that can no longer be read)."""
    from .tables import MapError

    for path in model_files:
        try:
            maps = _load(os.fspath(path), map_base, _mtime(path))
        except (OSError, MapError):
            continue
        for m in maps:
            if m.model_id == model:
                from decoders.table_decoder import TableDecoder

                return TableDecoder(m)
    from .registry import builtin_decoders

    return builtin_decoders().get(model)


def map_file(model: str, model_files=(), map_base: str | None = None, *,
             version: str = "") -> tuple[str, str, bytes] | None:
    """(file name, media type, bytes) of `model`'s tables, or None (generic, unknown)."""
    d = model_decoder(model, model_files, map_base)
    if d is None:
        return None
    note = getattr(d, "map_note", "")
    regmap = getattr(d, "map", None)
    if regmap is not None:
        head = [f"Register map of model {model!r}, as {_by(version)} decoded this capture with it.",
                "Format: docs/register-map-format.md of rs485-sniffer (`sniffer ... --model-file FILE` loads it);",
                "addr is the register's address on the wire (0-based), scale/unit give the value."]
        if note:
            head.append(note)
        path = regmap.path
        if path.lower().endswith(".toml") and os.path.isfile(path):
            with open(path, "rb") as fh:
                body = fh.read()
            head.append(f"The map file: {_shown(path)}.")
            return (f"{model}.registers.toml", TOML, "".join(f"# {line}\n" for line in head).encode() + body)
        from .mapformats import to_toml

        head.append(f"Read from {os.path.basename(path) or 'a map'} and written in that format.")
        return f"{model}.registers.toml", TOML, to_toml(regmap, "\n".join(head)).encode()
    tables = getattr(d, "tables", None)
    if tables is not None:
        doc = {"model": model, "written_by": _by(version), "note": note, **tables()}
        return f"{model}.tables.json", JSON, msgspec.json.format(msgspec.json.encode(doc))
    return None


def _shown(path: str) -> str:
    """A built-in map as the project names it (decoders/teco_a510/registers.toml), a user's by its name."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    full = os.path.abspath(path)
    inside = full.startswith(os.path.join(root, "decoders", ""))
    return os.path.relpath(full, root) if inside else os.path.basename(path)


def _by(version: str) -> str:
    return f"sniffer {version}" if version else "the sniffer"


def _mtime(path) -> float:
    try:
        return os.stat(path).st_mtime
    except OSError:
        return 0.0


@functools.lru_cache(maxsize=16)
def _load(path: str, base: str | None, mtime: float):
    from .mapformats import load_model_file

    return load_model_file(path, base)
