"""A lean core and optional extras: a command or option whose extra is missing says so in one line naming the
`pip install` to run, and exits 2 before it writes anything (sniffer.need); the extras table is pyproject's.

The modules of an extra are blocked here (None in sys.modules: their import fails as if not installed); a real
install without them is tests/test_install.py's.
"""

from __future__ import annotations

import re
import shutil
import sys
import tomllib
from pathlib import Path

import pytest

import sniffer
from sniffer import EXTRAS, MissingExtra, install_hint, need
from sniffer.cli import main

ROOT = Path(__file__).resolve().parents[1]
SIM = ROOT / "captures" / "sim" / "a510.mcap"
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _name(requirement: str) -> str:
    return re.split(r"[\[<>=!~;\s]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def test_extras_table_is_pyprojects():
    optional = PYPROJECT["optional-dependencies"]
    for extra, modules in EXTRAS.items():
        assert {_name(r) for r in optional[extra]} == set(modules.values()), extra
    core = {_name(r) for r in PYPROJECT["dependencies"]}
    assert not core & {d for modules in EXTRAS.values() for d in modules.values()}, "an extra's package in the core"
    (everything,) = optional["all"]
    name, _, given = everything.rstrip("]").partition("[")
    assert name == sniffer.DISTRIBUTION and set(given.split(",")) == set(EXTRAS), "[all] is every extra"
    assert f"{sniffer.DISTRIBUTION}[all]" in optional["test"]  # the suite runs every command
    assert PYPROJECT["name"] == sniffer.DISTRIBUTION


def _block(monkeypatch, extra: str) -> None:
    for module in EXTRAS[extra]:
        parts = module.split(".")
        for i in range(1, len(parts) + 1):
            monkeypatch.setitem(sys.modules, ".".join(parts[:i]), None)


def extra_inputs(tmp: Path) -> dict:
    cap = tmp / "in" / "a510.mcap"
    cap.parent.mkdir()
    shutil.copy(SIM, cap)
    ha = tmp / "in" / "meter.yaml"
    ha.write_text("modbus: []\n")
    return {"cap": str(cap), "folder": str(cap.parent), "yaml": str(ha), "out": str(tmp / "out")}


# (extra, argv, what the line names): every command and option that imports an extra's package
CASES = [
    ("fleet", "query {out}/ds 'SELECT 1'", "sniffer query"),
    ("fleet", "ingest {folder} --to {out}/ds", "sniffer ingest"),
    ("fleet", "export {cap} --to dataset {out}/ds", "export --to dataset"),
    ("fleet", "export {cap} --to parquet --out {out}/a.parquet", "--to parquet"),
    ("web", "serve --demo --no-out", "sniffer serve"),
    ("mqtt", "replay {cap} --quiet --mqtt mqtt://localhost/plant", "--mqtt"),
    ("maps", "replay {cap} --quiet --model-file {yaml}", "--model-file meter.yaml"),
    ("mcp", "mcp {cap}", "sniffer mcp"),
]


@pytest.mark.parametrize("extra,argv,what", CASES, ids=[f"{c[0]}:{c[1].split()[0]}" for c in CASES])
def test_missing_extra_is_one_line_naming_the_install(tmp_path, monkeypatch, capsys, extra, argv, what):
    paths = extra_inputs(tmp_path)
    (tmp_path / "out").mkdir()
    _block(monkeypatch, extra)
    import shlex

    rc = main([a.format(**paths) for a in shlex.split(argv)])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert what in err and f"the {extra} extra" in err, err
    assert err.rstrip().endswith(f"pip install 'rs485-sniffer[{extra}]'"), err
    assert not list((tmp_path / "out").iterdir()), "nothing is written before the extra is checked"


def test_need_passes_when_the_extra_is_installed():
    for extra in EXTRAS:
        need(extra, "test")


def test_the_hint_in_a_pipx_install_goes_through_pipx(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "prefix", str(tmp_path))
    assert install_hint("fleet") == "pip install 'rs485-sniffer[fleet]'"
    (tmp_path / "pipx_metadata.json").write_text("{}")
    assert install_hint("fleet") == "pipx runpip rs485-sniffer install 'rs485-sniffer[fleet]'"
    _block(monkeypatch, "maps")
    with pytest.raises(MissingExtra, match=r"pipx runpip rs485-sniffer install 'rs485-sniffer\[maps\]'"):
        need("maps", "--model-file x.yaml")
