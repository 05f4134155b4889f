"""The tool as a field engineer installs it: the wheel, in a fresh virtual environment, without extras.

The wheel is built once from a copy of the package (pip wheel, without build isolation where the setuptools
here can, else with it) and installed with its core dependencies only.  From a folder outside the checkout
(nothing of it importable) it then runs `demo`, `replay`, `decode` with each built-in model, `report` and the
CSV export, each giving what this checkout gives; every command of an extra names its extra; and the fleet
extra, installed by the command its message names, makes `query` work.  pip reaches its index here and in CI.
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

from test_extras import CASES, extra_inputs

pytestmark = [pytest.mark.slow, pytest.mark.timeout(1200)]

ROOT = Path(__file__).resolve().parents[1]
EXTRA_MODULES = ("pyarrow", "duckdb", "paho", "textual_serve", "yaml", "mcp")
# *.so: the compiled hot path an editable install built in place (the wheel builds its own from sniffer/_hot.c)
SKIP = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build", "*.so")


def _env() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


def _run(argv, cwd, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in argv], cwd=cwd, env=_env(), capture_output=True, text=True,
                          timeout=timeout)


class Install:
    def __init__(self, root: Path, wheel: Path, work: Path) -> None:
        self.root, self.wheel, self.work = root, wheel, work
        self.python = root / "bin" / "python"

    def sniffer(self, *args, timeout=300) -> subprocess.CompletedProcess:
        return _run([self.root / "bin" / "sniffer", *args], self.work, timeout)

    def pip(self, *args) -> subprocess.CompletedProcess:
        return _run([self.python, "-m", "pip", *args], self.work, timeout=900)


def here(*args, cwd) -> subprocess.CompletedProcess:
    """The same command run by this checkout's sniffer (the reference)."""
    return _run([sys.executable, "-m", "sniffer", *args], cwd)


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[Path, Path]:
    """(the wheel, the copy of the package it was built from)."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy(ROOT / name, src / name)
    for package in ("sniffer", "decoders"):
        shutil.copytree(ROOT / package, src / package, ignore=SKIP)
    dist = tmp_path_factory.mktemp("dist")
    for isolation in (["--no-build-isolation"], []):  # offline where this setuptools can build a wheel
        r = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-w", dist, src], src)
        if r.returncode == 0:
            break
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    (wheel,) = dist.glob("rs485_sniffer-*.whl")
    return wheel, src


@pytest.fixture(scope="module")
def core(built, tmp_path_factory) -> Install:
    wheel, _ = built
    root = tmp_path_factory.mktemp("venv")
    r = _run([sys.executable, "-m", "venv", root], root)
    assert r.returncode == 0, r.stderr
    work = tmp_path_factory.mktemp("field")
    inst = Install(root, wheel, work)
    r = inst.pip("install", wheel)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    r = inst.sniffer("demo", "--headless", "--duration", "3", "--out", "demo.mcap")
    assert r.returncode == 0, r.stderr
    inst.demo = r
    return inst


def test_the_wheel_holds_every_file_of_the_packages(built):
    wheel, src = built
    names = set(zipfile.ZipFile(wheel).namelist())
    files = [p.relative_to(src).as_posix() for package in ("sniffer", "decoders")
             for p in (src / package).rglob("*") if p.is_file()]
    assert any(f.endswith("registers.toml") for f in files) and any(f.endswith(".js") for f in files)
    assert not [f for f in files if f not in names], "files of the packages missing from the wheel"


def test_the_core_install_has_no_extra(core):
    code = "import importlib.util as u, sys; print([m for m in sys.argv[1:] if u.find_spec(m)])"
    r = _run([core.python, "-c", code, *EXTRA_MODULES], core.work)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stdout + r.stderr
    r = _run([core.python, "-c", "import sniffer; print(sniffer.__file__)"], core.work)
    assert str(core.root) in r.stdout, "the installed package, not the checkout's"


def test_every_module_imports_without_the_extras(core):
    """An extra's package is imported where it is used, never at a module's top (the TUI's modules included)."""
    code = """
import importlib, pkgutil, sys
bad = []
for top in ("sniffer", "decoders"):
    pkg = importlib.import_module(top)
    for m in pkgutil.walk_packages(pkg.__path__, top + "."):
        if m.name == "sniffer.commands.pytest_plugin" or m.name.endswith(".__main__"):  # pytest's; runs the CLI
            continue
        try:
            importlib.import_module(m.name)
        except Exception as e:
            bad.append(f"{m.name}: {e!r}")
print("\\n".join(bad))
"""
    r = _run([core.python, "-c", code], core.work)
    assert r.returncode == 0 and not r.stdout.strip(), r.stdout + r.stderr


def test_demo_replay_report_and_csv_as_the_checkout_gives_them(core):
    assert "sniffer wrote 0 bytes to the bus" in core.demo.stderr
    assert len(core.demo.stdout.splitlines()) > 10
    assert "No such file" not in core.demo.stderr and "Traceback" not in core.demo.stderr
    w = core.work
    r = core.sniffer("replay", "demo.mcap")
    assert r.returncode == 0, r.stderr
    assert r.stdout == here("replay", "demo.mcap", cwd=w).stdout and len(r.stdout.splitlines()) > 10
    r = core.sniffer("export", "demo.mcap", "--to", "csv", "--out", "core.csv")
    assert r.returncode == 0, r.stderr
    assert here("export", "demo.mcap", "--to", "csv", "--out", "dev.csv", cwd=w).returncode == 0
    for stem in ("", ".points"):
        assert (w / f"core{stem}.csv").read_bytes() == (w / f"dev{stem}.csv").read_bytes()
    r = core.sniffer("report", "demo.mcap", "--out", "report.html")
    assert r.returncode == 0, r.stderr
    page = (w / "report.html").read_text()
    for asset in ("report.js", "report.css", "vendor/uPlot.iife.min.js", "vendor/uPlot.min.css"):
        text = (ROOT / "sniffer" / "report" / asset).read_text().strip()
        assert text[:300] in page and text[-300:] in page, f"{asset} is not in the report"


def _decode_args() -> list[tuple[str, list[str]]]:
    """(model, decode's arguments) for each built-in model: its manual's example frames (a model without
    examples of its own decodes another's), on the unit each frame names."""
    from decoders.registry import builtin_decoders

    out = []
    for model, d in builtin_decoders().items():
        regmap = getattr(d, "map", None)
        folder = Path(regmap.path).parent if regmap else ROOT / "decoders" / type(d).__module__.split(".")[1]
        if not (folder / "examples.toml").exists():
            folder = ROOT / "decoders" / "tds_v8"
        examples = tomllib.loads((folder / "examples.toml").read_text())["examples"]
        protocol = "pd-rtu" if any(ex.get("protocol") == "pd-rtu" for ex in examples) else "modbus-rtu"
        frames = [ex["hex"] for ex in examples if ex.get("protocol", "modbus-rtu") == protocol and "hex" in ex][:12]
        units = sorted({int(h[:2], 16) for h in frames})
        out.append((model, ["--protocol", protocol, *[a for u in units for a in ("--device", f"{u}={model}")],
                            *frames]))
    return out


def test_decode_with_each_built_in_model(core):
    cases = _decode_args()
    assert len(cases) >= 5
    for model, args in cases:
        r = core.sniffer("decode", "--format", "jsonl", *args)
        assert r.returncode == 0 and "Traceback" not in r.stderr, (model, r.stderr)
        records = [json.loads(line) for line in r.stdout.splitlines()]
        assert [rec for rec in records if rec["model"] == model and rec["crc_ok"]], (model, r.stdout[:500])
        assert r.stdout == here("decode", "--format", "jsonl", *args, cwd=core.work).stdout, model


@pytest.mark.parametrize("extra,argv,what", CASES, ids=[f"{c[0]}:{c[1].split()[0]}" for c in CASES])
def test_each_extras_command_names_its_extra(core, tmp_path, extra, argv, what):
    paths = extra_inputs(tmp_path)
    (tmp_path / "out").mkdir()
    r = core.sniffer(*[a.format(**paths) for a in shlex.split(argv)], timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert what in r.stderr and f"pip install 'rs485-sniffer[{extra}]'" in r.stderr, r.stderr
    assert not list((tmp_path / "out").iterdir())


def test_the_fleet_extra_installed_as_the_message_says_makes_query_work(core):
    """Last in this file: it adds the extra to the core install the tests above use."""
    r = core.sniffer("query", "ds", "SELECT 1")
    hint = r.stderr.rstrip().rsplit(": ", 1)[1]
    assert hint.startswith("pip install "), r.stderr
    r = core.pip(*shlex.split(hint)[1:], "--find-links", core.wheel.parent)  # pip install ...: its pip
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    r = core.sniffer("export", "demo.mcap", "--to", "dataset", "ds")
    assert r.returncode == 0, r.stderr
    r = core.sniffer("query", "ds", "SELECT count(*) AS n FROM frames", "--format", "csv")
    assert r.returncode == 0, r.stderr
    assert core.sniffer("export", "demo.mcap", "--to", "csv", "--out", "n.csv").returncode == 0
    frames = len((core.work / "n.csv").read_text().splitlines()) - 1
    assert r.stdout.split() == ["n", str(frames)] and frames > 10
    r = core.sniffer("export", "demo.mcap", "--to", "parquet", "--out", "demo.parquet")
    assert r.returncode == 0 and (core.work / "demo.parquet").stat().st_size > 0, r.stderr
