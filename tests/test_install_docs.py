"""docs/install.md stays true: its udev rule is troubleshooting.md's, its extras table is sniffer.EXTRAS, and the
bus file it shows is one the sniffer reads."""

from __future__ import annotations

import re
from pathlib import Path

from sniffer import EXTRAS

DOCS = Path(__file__).resolve().parent.parent / "docs"
INSTALL = (DOCS / "install.md").read_text()


def _udev_rule(text: str) -> str:
    (block,) = [b for b in re.findall(r"```sh\n(.*?)```", text, re.S) if "udev/rules.d" in b]
    return block


def test_the_udev_rule_is_troubleshootings():
    rule = _udev_rule(INSTALL)
    assert 'DRIVER=="ftdi_sio"' in rule and "latency_timer" in rule and "dialout" in rule
    assert rule == _udev_rule((DOCS / "troubleshooting.md").read_text())


def test_the_extras_table_is_the_extras():
    rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", INSTALL, re.M))
    for extra, modules in EXTRAS.items():
        assert [p.strip() for p in rows[extra].split(",")] == list(modules.values()), extra
    assert {"all", "test"} <= set(rows)


def test_the_bus_file_example_reads(tmp_path):
    from sniffer.capture.busfile import load_bus_file

    (block,) = re.findall(r"```toml\n(.*?)```", INSTALL, re.S)
    path = tmp_path / "plant.toml"
    path.write_text(block)
    bus = load_bus_file(str(path))
    ports = [p for link in bus.links for p in link.ports]
    assert [link.tap for link in bus.links] == [False, True] and len(ports) == 3
    assert all(p.startswith("/dev/serial/by-id/") for p in ports)
