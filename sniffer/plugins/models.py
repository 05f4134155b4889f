"""The `rs485_sniffer.models` group: drive models from other packages.

An entry gives one of:
  * a decoder: an object with `model` (its --device id), `codes` (the annotation codes it may emit, a tuple
    of sniffer.codes.Code) and `decode(frame, request, state)` (decoders/base.py's Decoder);
  * a zero-argument callable (a class, a function) that returns such a decoder, or a map path;
  * a register map file (TOML, CSV or Home Assistant YAML, docs/register-map-format.md) as a path: a str,
    a pathlib.Path or an importlib.resources file; decoders.registry reads it as --model-file would.
"""

from __future__ import annotations

import os
import re

from sniffer.codes import Code

GROUP = "rs485_sniffer.models"
_ID = re.compile(r"^[a-z0-9][a-z0-9._-]{0,39}$")


def check_decoder(d, where: str = "") -> object:
    """`d` if it is a decoder; TypeError / ValueError saying what is missing."""
    model = getattr(d, "model", None)
    if not isinstance(model, str) or not _ID.match(model):
        raise ValueError(f"{where}model must be an id of lower-case letters, digits, '.', '_' or '-' "
                         f"(--device UNIT=ID), not {str(model)[:40]!r}")
    codes = getattr(d, "codes", None)
    if not isinstance(codes, (tuple, list)) or not all(isinstance(c, Code) for c in codes):
        raise TypeError(f"{where}codes must be a tuple of sniffer.codes.Code (the annotation codes it may emit)")
    if not callable(getattr(d, "decode", None)):
        raise TypeError(f"{where}has no decode(frame, request, state) method")
    return d


def _map_path(obj) -> str | None:
    if isinstance(obj, (str, os.PathLike)):
        return os.fspath(obj)
    if hasattr(obj, "is_file") and hasattr(obj, "read_bytes") and hasattr(obj, "name"):  # importlib.resources
        import importlib.resources

        with importlib.resources.as_file(obj) as p:  # a file inside a zip would be extracted: kept only if real
            return os.fspath(p)
    return None


def check(name: str, obj) -> object:
    """A decoder, or the path of a map file (decoders.registry loads it), from an entry's object."""
    path = _map_path(obj)
    if path is None and (isinstance(obj, type) or (callable(obj) and not hasattr(obj, "decode"))):
        obj = obj()  # a class or a factory
        path = _map_path(obj)
    if path is not None:
        if not os.path.isfile(path):
            raise ValueError(f"its register map {path} is not a file")
        return path
    return check_decoder(obj)


def model_plugins():
    """The plugins of the models group that loaded and passed (Plugin.obj: a decoder or a map's path)."""
    from sniffer.plugins.entry import load

    return load(GROUP, check)
