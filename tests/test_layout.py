"""The tree is the map: packages by stage, each with a face, no private name imported across modules.

The import contracts themselves (framing imports nothing above it, no cycles, ...) are pyproject.toml's
`[tool.importlinter]`, checked by `lint-imports` in .ci/run.
"""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNIFFER = ROOT / "sniffer"
LOOSE_ALLOWED = 6  # beside __init__, __main__ and cli
FACES = ("sniffer.framing", "sniffer.capture", "sniffer.sources", "sniffer.processes", "sniffer.analysis",
         "sniffer.decoding")


def _py_files():
    for top in ("sniffer", "decoders"):
        yield from sorted((ROOT / top).rglob("*.py"))


def test_at_most_six_loose_modules_in_sniffer():
    loose = sorted(p.stem for p in SNIFFER.glob("*.py") if p.stem not in ("__init__", "__main__", "cli"))
    assert len(loose) <= LOOSE_ALLOWED, loose


def test_every_package_has_a_face_with_a_docstring():
    for init in sorted(SNIFFER.rglob("__init__.py")):
        if "vendor" in init.parts:
            continue
        doc = ast.get_docstring(ast.parse(init.read_text()))
        assert doc, f"{init.relative_to(ROOT)} has no docstring saying what the package is"


@pytest.mark.parametrize("package", FACES)
def test_each_face_exports_resolve(package):
    mod = importlib.import_module(package)
    assert mod.__all__ == sorted(mod.__all__)
    for name in mod.__all__:
        assert getattr(mod, name) is not None, f"{package}.{name}"
    with pytest.raises(AttributeError):
        mod.no_such_name  # noqa: B018 - the face refuses a name it does not export


def test_no_module_imports_another_modules_private_names():
    bad = []
    for path in _py_files():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ("sniffer", "decoders"):
                bad += [f"{path.relative_to(ROOT)}:{node.lineno} {node.module}.{a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    assert not bad, bad


HISTORY = re.compile(r"\b(issue|stop) \d+\b|(?:\(|, )20\d\d-\d\d-\d\d\b", re.IGNORECASE)  # not an example date


def test_code_comments_say_why_not_when():
    """Issue numbers and dates belong in commit messages and benchmarks/, not in the code."""
    bad = []
    for path in _py_files():
        for i, line in enumerate(path.read_text().splitlines(), 1):
            if HISTORY.search(line):
                bad.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()[:80]}")
    assert not bad, "\n".join(bad)


def test_every_module_imports():
    """A module that fails at import (a merge that renamed what it used) fails here, in the fast lane."""
    import pkgutil

    bad = []
    for top in ("sniffer", "decoders"):
        pkg = importlib.import_module(top)
        for m in pkgutil.walk_packages(pkg.__path__, top + "."):
            if m.name == "sniffer.commands.pytest_plugin" or m.name.endswith(".__main__"):
                continue
            try:
                importlib.import_module(m.name)
            except ImportError as e:
                if e.name and e.name.split(".")[0] not in ("sniffer", "decoders"):
                    continue  # an extra that is not installed: test_install checks those
                bad.append(f"{m.name}: {e!r}")
            except Exception as e:  # noqa: BLE001 - every kind of import failure is the finding
                bad.append(f"{m.name}: {e!r}")
    assert not bad, bad
