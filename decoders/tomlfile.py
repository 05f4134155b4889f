"""Read a TOML file (bus files, register maps) with one clear error line.

Refused, each as `error("<path>: <why>")`, by sniffer.inputs' rules: a missing or unreadable file, a
directory, FIFO or device (reading one could block), a file over its cap (CAPS), bytes that are not
UTF-8; and here: TOML that does not parse, nesting deep enough to exhaust Python's recursion limit,
numbers too long to convert.  A float that is not finite (nan, inf) is refused by the field that reads it
(busfile.py, regtypes.py) with the field's own words.
"""

from __future__ import annotations

import tomllib

from sniffer.inputs import CAPS
from sniffer.inputs import read_text as _read_text

KIND = "a bus file or register map"
MAX_BYTES = CAPS[KIND]


def read_text(path: str, error: type[Exception], what: str = KIND, bom: bool = False) -> str:
    """A small text file (UTF-8; with `bom`, a byte-order mark allowed), or `error("<path>: <why>")`:
    never blocks on a FIFO, never reads more than MAX_BYTES of a device or a huge file."""
    return _read_text(path, MAX_BYTES, what, error, bom)


def read_toml(path: str, error: type[Exception]) -> dict:
    """The document, or `error("<path>: <why>")`."""
    text = read_text(path, error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML ({str(e)[:200]})") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply to be a bus file or register map") from None
    except ValueError as e:  # e.g. an integer over Python's digit limit
        raise error(f"{path}: not usable TOML ({str(e)[:200]})") from None
