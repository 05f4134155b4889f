"""Register maps in the formats plants already have, and the TOML the project writes.

    load_model_file("meter.csv", base="1")   # -> [RegisterMap]: what --model-file loads
    to_toml(regmap)                           # -> the map as a registers.toml (tomlout.py)

By extension: .toml (docs/register-map-format.md), .csv (csvmap.py), .yaml / .yml (Home
Assistant modbus, hayaml.py).  A file gives one map, or one per device where it describes
several (a Home Assistant file with sensors of several slaves).
"""

from __future__ import annotations

import os

from sniffer import need

from ..tables import MapError, RegisterMap, load_map
from .common import BASES, parse_base  # noqa: F401 - the flag's choices
from .tomlout import to_toml  # noqa: F401 - re-exported

SUFFIXES = (".toml", ".csv", ".yaml", ".yml")


def load_model_file(path: str, base: str | None = None) -> list[RegisterMap]:
    """The register map(s) in `path`, by its extension; MapError (one line naming file and row) if unusable.

    `base` ("0", "1", "modicon"; --map-base) says how a CSV counts its addresses; a TOML map is
    always 0-based (PDU addresses), as are Home Assistant's."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".csv":
        from .csvmap import load_csv

        return load_csv(path, base)
    if ext in (".yaml", ".yml"):
        need("maps", f"--model-file {os.path.basename(path)} (a Home Assistant YAML map)")
        from .hayaml import load_ha_yaml

        return load_ha_yaml(path, base)
    if ext == ".toml" or not ext:
        return [load_map(path)]
    raise MapError(f"{path}: unknown register-map format {ext!r} (one of {', '.join(SUFFIXES)})")
