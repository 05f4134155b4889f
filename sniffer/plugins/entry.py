"""Reading an entry-point group: each entry loaded once per process, checked by its group, kept or left out.

A plugin that cannot be imported, raises while loading, or gives something of the wrong shape is one
warning line on stderr (`sniffer: warning: plugin NAME (GROUP, from DIST VERSION): WHY; left out`), said
once, and the rest of the tool works without it.  `broken()` lists those for `sniffer models`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

from sniffer.stderr import say


@dataclass(frozen=True)
class Plugin:
    """A loaded, checked entry: what it gave, and where it came from."""

    group: str
    name: str  # the entry point's name
    value: str  # "module:attribute"
    dist: str  # the distribution that declares it, "name version"
    location: str  # where that distribution is installed
    obj: object  # what the group's check made of the loaded object


@dataclass(frozen=True)
class Broken:
    group: str
    name: str
    value: str
    dist: str
    why: str


_broken: dict[tuple[str, str, str], Broken] = {}


@functools.cache
def entries(group: str) -> tuple:
    """The entry points of `group` (importlib.metadata), each distribution's once, in name order (read once per
    process: every parser build asks for the protocols' names)."""
    from importlib.metadata import entry_points

    seen, out = set(), []
    for ep in sorted(entry_points(group=group), key=lambda e: (e.name, e.value)):
        if (ep.name, ep.value) not in seen:
            seen.add((ep.name, ep.value))
            out.append(ep)
    return tuple(out)


def _dist(ep) -> tuple[str, str]:
    d = getattr(ep, "dist", None)
    if d is None:
        return "an unknown distribution", ""
    where = ""
    try:
        where = str(d.locate_file(""))
    except Exception:  # noqa: BLE001 - a distribution that cannot say where it is still names itself
        pass
    return f"{d.metadata['Name']} {d.version}", where


def warn(group: str, name: str, value: str, dist: str, why: str) -> None:
    """The one line for a plugin left out (once per plugin and process)."""
    key = (group, name, value)
    if key in _broken:
        return
    why = " ".join(why.split())[:300]
    _broken[key] = Broken(group, name, value, dist, why)
    say(f"warning: plugin {name} ({group}, {value}, from {dist}): {why}; left out")


def broken() -> list[Broken]:
    """The plugins left out so far in this process (each was said once)."""
    return list(_broken.values())


@functools.cache
def load(group: str, check: Callable[[str, object], object]) -> tuple[Plugin, ...]:
    """Every entry of `group` that loads and passes `check(name, obj)` (which gives what to keep, or raises
    TypeError / ValueError saying what is wrong); the others warned about and left out."""
    out = []
    for ep in entries(group):
        dist, where = _dist(ep)
        try:
            obj = ep.load()
        except Exception as e:  # noqa: BLE001 - any failure of third-party code at import is the plugin's
            warn(group, ep.name, ep.value, dist, f"cannot be loaded: {type(e).__name__}: {e}")
            continue
        try:
            kept = check(ep.name, obj)
        except (TypeError, ValueError) as e:
            warn(group, ep.name, ep.value, dist, f"wrong interface: {e}")
            continue
        except Exception as e:  # noqa: BLE001 - a factory that raises is the plugin's failure too
            warn(group, ep.name, ep.value, dist, f"failed: {type(e).__name__}: {e}")
            continue
        out.append(Plugin(group, ep.name, ep.value, dist, where, kept))
    return tuple(out)
