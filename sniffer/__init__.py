"""Passive RS-485 sniffer for PLC <-> drive links.

Pipeline: source -> framer -> pairer -> decoder registry -> sinks.
Every stage is sans-I/O; `sniffer.capture.pipeline.Pipeline` drives them for live
capture, replay and tests alike.

Beside the version and the faces' helper, the optional extras: `need("fleet", "sniffer query")` where a
command or option first needs one (MissingExtra: one line naming the `pip install`, exit 2).
"""

__version__ = "0.1.0"


def face(package: str, exports: dict[str, str]):
    """A package face's `__getattr__`: `exports` maps each public name to the module that defines it, imported
    when the name is first used (a face never makes `import sniffer.formats` load pyarrow)."""
    import importlib
    import sys

    def __getattr__(name: str):
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__


# The optional extras (pyproject.toml's [project.optional-dependencies]): extra -> {module: its distribution}.
EXTRAS = {
    "fleet": {"pyarrow": "pyarrow", "duckdb": "duckdb"},  # Parquet export, export --to dataset, ingest, query
    "mqtt": {"paho.mqtt.client": "paho-mqtt"},  # --mqtt
    "web": {"textual_serve.server": "textual-serve"},  # serve
    "maps": {"yaml": "pyyaml"},  # --model-file x.yaml (Home Assistant modbus)
    "mcp": {"mcp.server.mcpserver": "mcp"},  # sniffer mcp: an assistant's read-only tools (the SDK's v2 server)
}
DISTRIBUTION = "rs485-sniffer"


class MissingExtra(Exception):
    """A command or option needs an optional extra that is not installed: one line naming the install, exit 2."""


def need(extra: str, what: str) -> None:
    """Raise MissingExtra ("WHAT needs the EXTRA extra (its packages): pip install ...") unless every module
    of `extra` is installed.  Called where a command or option first needs the extra, before any output
    exists.  The modules are found, not imported (a Parquet export does not load DuckDB)."""
    from importlib.util import find_spec

    for module in EXTRAS[extra]:
        try:
            found = find_spec(module) is not None
        except ImportError:  # its parent package is missing
            found = False
        if not found:
            packages = ", ".join(EXTRAS[extra].values())
            raise MissingExtra(f"{what} needs the {extra} extra ({packages}): {install_hint(extra)}")


def install_hint(extra: str) -> str:
    """The command that adds `extra` to this installation (a pipx install's venv is changed through pipx)."""
    import os
    import sys

    if os.path.isfile(os.path.join(sys.prefix, "pipx_metadata.json")):
        return f"pipx runpip {DISTRIBUTION} install '{DISTRIBUTION}[{extra}]'"
    return f"pip install '{DISTRIBUTION}[{extra}]'"
