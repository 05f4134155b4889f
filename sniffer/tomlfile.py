"""Read a TOML file (bus files, register maps) with one clear error line."""

from __future__ import annotations

import tomllib


def read_toml(path: str, error: type[Exception]) -> dict:
    """The document, or `error("<path>: <why>")` for a missing file or bad TOML."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except OSError as e:
        raise error(f"{path}: {e.strerror or e}") from None
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML ({e})") from None
