"""The commands check / diff / export through the CLI (sniffer.cli.main, in this process)."""

from __future__ import annotations

from pathlib import Path

import orjson
import pytest

from sniffer import cli

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
A510 = str(CAPTURES / "sim" / "a510.mcap")
DEFAULT = str(CAPTURES / "sim" / "default.mcap")
WIZ = str(CAPTURES / "refcaptures" / "sigrok" / "wizmodbus.bytes.csv")


def run(*argv) -> int:
    return cli.main(list(argv))


def test_check_exit_codes(tmp_path, capsys):
    g = str(tmp_path / "g.txt")
    assert run("check", A510, "--golden", g) == 2
    assert "no such golden" in capsys.readouterr().err
    assert run("check", WIZ, "--golden", g, "--update-golden") == 2  # no baud in a byte CSV
    assert "baud" in capsys.readouterr().err
    assert run("check", WIZ, "--golden", g, "--baud", "9600", "--update-golden") == 0
    assert run("check", WIZ, "--golden", g, "--baud", "9600") == 0
    lines = Path(g).read_text().splitlines()
    lines[1] = lines[1].replace(" | ", " | X", 1)  # the first frame's line (the header is a comment)
    Path(g).write_text("\n".join(lines) + "\n")
    assert run("check", WIZ, "--golden", g, "--baud", "9600") == 1
    assert capsys.readouterr().out.startswith(f"sniffer check: {WIZ} differs from {g}")
    assert run("check", WIZ, "--golden", g, "--baud", "9600", "--diff") == 1
    assert "\n--- " in capsys.readouterr().out


def test_check_time_tolerance_flag(tmp_path):
    g = tmp_path / "g.txt"
    assert run("check", A510, "--golden", str(g), "--update-golden") == 0
    lines = g.read_text().splitlines()
    head, _, rest = lines[1].partition(" | ")
    t, lat = head.split()
    lines[1] = f"{float(t) + 0.004:.6f} {lat} | {rest}"
    g.write_text("\n".join(lines) + "\n")
    assert run("check", A510, "--golden", str(g)) == 1
    assert run("check", A510, "--golden", str(g), "--time-tol-ms", "5") == 0


def test_diff_text_and_json(capsys):
    assert run("diff", A510, A510) == 0
    assert "no semantic difference" in capsys.readouterr().out
    assert run("diff", DEFAULT, A510, "--format", "json") == 1
    d = orjson.loads(capsys.readouterr().out)
    assert d["same"] is False and d["units"]["models"]["1"] == "a510"


def test_diff_device_flag_applies_to_both(capsys):
    assert run("diff", A510, A510, "--device", "1=generic") == 0


@pytest.mark.parametrize("fmt", ["csv", "parquet", "pcap", "pcapng", "mcap"])
def test_export_every_format(tmp_path, fmt, capsys):
    out = tmp_path / f"wiz.{fmt}"
    assert run("export", WIZ, "--to", fmt, "--out", str(out), "--baud", "9600") == 0
    assert out.stat().st_size > 0
    assert "(88 frames)" in capsys.readouterr().err


def test_readme_worked_example_names_the_changed_register(tmp_path):
    """docs/regression.md: change one drive parameter in the simulator, record again, `sniffer diff` names it."""
    import subprocess
    import sys

    sn = [sys.executable, "-m", "sniffer"]
    base = ["simulate", "--scenario", "default", "--seed", "4", "--duration", "5"]
    assert subprocess.run(sn + base + ["--out", "before.mcap"], cwd=tmp_path, capture_output=True).returncode == 0
    assert subprocess.run(sn + base + ["--param", "unit2.rated_current_a=11.0", "--out", "after.mcap"],
                          cwd=tmp_path, capture_output=True).returncode == 0
    r = subprocess.run(sn + ["diff", "before.mcap", "after.mcap"], cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 1, r.stderr
    changed = [l for l in r.stdout.splitlines() if l.startswith("  ~ u")]
    assert changed and all(l.startswith("  ~ u2 ") for l in changed)  # only unit 2 changed
    assert any("holding[8451]" in l and "->" in l for l in changed)
    page = (Path(__file__).resolve().parent.parent / "docs" / "regression.md").read_text()
    for line in r.stdout.splitlines():
        assert line in page, line
    bad = subprocess.run(sn + base + ["--param", "unit9.rated_current_a=1", "--out", "x.mcap"], cwd=tmp_path,
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "no unit 9" in bad.stderr and "Traceback" not in bad.stderr
