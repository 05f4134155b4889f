"""Passive RS-485 sniffer for PLC <-> drive links.

Pipeline: source -> framer -> pairer -> decoder registry -> sinks.
Every stage is sans-I/O; `sniffer.capture.pipeline.Pipeline` drives them for live
capture, replay and tests alike.
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
