"""Table lint: every register map loads, ids unique, no overlaps, every row cites its manual."""

from __future__ import annotations

from pathlib import Path

import pytest

from decoders.tables import MapError, lint, load_map

MAPS = sorted((Path(__file__).resolve().parent.parent / "decoders").glob("*/registers.toml"))


def test_maps_exist():
    assert MAPS


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.parent.name)
def test_map_lints_clean(path):
    m = load_map(path)
    assert m.registers and m.model_id
    assert lint(m) == []
    for r in m.registers.values():
        assert r.section.strip(), r


def test_broken_map_is_one_clear_error(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('registers = [ { addr = 1, name = "a" }, { addr = 1, name = "b" } ]\n[model]\nid = "x"\n')
    with pytest.raises(MapError, match="listed twice"):
        load_map(bad)
    bad.write_text("not toml [")
    with pytest.raises(MapError, match="not valid TOML"):
        load_map(bad)
