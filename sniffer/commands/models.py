"""`sniffer models`: the drive models and line protocols installed, and where each comes from (built in, or a
plugin's package: sniffer.plugins)."""

from __future__ import annotations

import json
import sys

from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_OK
from sniffer.commands.flags import command_parser


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "models", help="list the drive models and line protocols installed, and where they come from",
        description="""\
            The models --device UNIT=MODEL takes and the protocols --protocol takes: the ones shipped, and those
            of installed plugin packages (the entry points rs485_sniffer.models and rs485_sniffer.protocols,
            docs/plugins.md), each with its package, version and folder.  A plugin that does not load is
            listed at the end with why (and said in one warning line).""",
        examples=["sniffer models", "sniffer models --format json"])
    p.add_argument("--format", choices=["text", "json"], default="text", help="text for people, or JSON")


def _origin(plugin) -> dict:
    return {"from": "plugin", "package": plugin.dist, "entry_point": f"{plugin.group}:{plugin.name}",
            "object": plugin.value, "location": plugin.location}


def listing() -> dict:
    """{"models": [...], "protocols": [...], "left_out": [...]}: what `sniffer models` shows."""
    from decoders.registry import builtin_decoders, plugin_models
    from sniffer.plugins import broken
    from sniffer.protocols import PROTOCOLS, known

    models = [{"model": m, "from": "built in"} for m in builtin_decoders()]
    for m, (d, plugin) in plugin_models().items():
        row = {"model": m, **_origin(plugin)}
        path = getattr(getattr(d, "map", None), "path", None)
        if path:
            row["map"] = str(path)
        models.append(row)
    plugins = {p.obj.name: p for p in _protocol_plugins()}
    protocols = []
    for name, p in known().items():
        row = {"protocol": name, "default_model": p.default_model}
        row.update({"from": "built in"} if name in PROTOCOLS else _origin(plugins[name]))
        protocols.append(row)
    left = [{"name": b.name, "entry_point": b.group, "object": b.value, "package": b.dist, "why": b.why}
            for b in broken()]
    return {"models": models, "protocols": protocols, "left_out": left}


def _protocol_plugins():
    from sniffer.plugins import protocol_plugins

    return protocol_plugins()


def run(spec: CaptureSpec, args) -> int:
    got = listing()
    if args.format == "json":
        sys.stdout.write(json.dumps(got, indent=2) + "\n")
        return EXIT_OK
    out = ["models (--device UNIT=MODEL):"]
    for m in got["models"]:
        out.append(f"  {m['model']:<14} {_where(m)}" + (f", map {m['map']}" if m.get("map") else ""))
    out.append("protocols (--protocol):")
    for p in got["protocols"]:
        out.append(f"  {p['protocol']:<14} {_where(p)}; default model {p['default_model']}")
    if got["left_out"]:
        out.append("left out (plugins that do not load):")
        for b in got["left_out"]:
            out.append(f"  {b['name']:<14} {b['entry_point']} {b['object']}, from {b['package']}: {b['why']}")
    sys.stdout.write("\n".join(out) + "\n")
    return EXIT_OK


def _where(row: dict) -> str:
    if row["from"] == "built in":
        return "built in"
    return f"plugin {row['package']} ({row['entry_point']} = {row['object']}) in {row['location']}"
