"""A register map's [model] table as one typed structure (decoders/model_info.py ModelInfo): checked once when the
map loads, read as attributes everywhere, written back as it was read."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from decoders.mapformats.tomlout import to_toml
from decoders.model_info import KEYS, NOTES, ModeCommand, ModelInfo, ModeRegister
from decoders.tables import MapError, load_map

MAPS = sorted(Path("decoders").glob("*/registers.toml"))


@pytest.mark.parametrize("path", MAPS, ids=[p.parent.name for p in MAPS])
def test_every_builtin_model_table_is_typed(path):
    info = load_map(path).model
    assert isinstance(info, ModelInfo) and info.id
    for name, f in KEYS.items():
        v = getattr(info, name)
        if name in info.table:
            convert = f.metadata["convert"]
            assert v == (convert(info.table[name]) if convert else info.table[name])
        else:
            assert v == f.default  # what the map does not say is the field's default, for every reader
    assert isinstance(info.vendor_function_codes, tuple) and isinstance(info.fault_registers, tuple)


def test_tds_v8_mode_registers_are_structures():
    info = load_map("decoders/tds_v8/registers.toml").model
    assert info.mode_register == ModeRegister(0x0020, 4)
    assert info.mode_command == ModeCommand(0x0000, 8, 9)
    assert info.table["mode_command"]["auto_clear"] is True  # a note the structure does not read, kept
    assert all(isinstance(r, tuple) and len(r) == 2 for r in info.prg_only_ranges)


@pytest.mark.parametrize("path", MAPS, ids=[p.parent.name for p in MAPS])
def test_the_model_table_is_written_back_as_read(path, tmp_path):
    m = load_map(path)
    again = tmp_path / "again.toml"
    again.write_text(to_toml(m))
    back = load_map(again).model
    assert back == m.model and back.table == m.model.table  # the notes too (NOTES: kept as written)


def test_a_model_built_in_code_writes_the_keys_that_say_something():
    info = ModelInfo(id="pump", name="learned", function_codes=(3, 6), mode_register=ModeRegister(1, 2))
    assert info.to_table() == {"id": "pump", "name": "learned", "function_codes": [3, 6],
                               "mode_register": {"addr": 1, "bit": 2}}
    assert ModelInfo.from_table(info.to_table(), MapError) == info


def test_units_takes_either_wording():
    assert ModelInfo.from_table({"id": "a", "unit_address_range": [1, 31]}, MapError).units == (1, 31)
    assert ModelInfo.from_table({"id": "a", "unit_addresses": [2, 9]}, MapError).units == (2, 9)
    assert ModelInfo.from_table({"id": "a"}, MapError).units is None


def test_notes_and_keys_are_apart():
    assert not set(KEYS) & NOTES


def test_nothing_reads_the_model_table_with_get():
    """The readers (decoders, the identifier, the simulator) take ModelInfo's attributes: a default of their own
    for a key (`.get("mode_register", {...})`) would be a second, unchecked definition."""
    readers = [p for top in ("decoders", "sniffer") for p in Path(top).rglob("*.py")]
    pattern = re.compile(r"\.model\s*\.\s*get\(|\.model\[|\bmodel\.get\(\"(" + "|".join(KEYS) + r")\"")
    found = [f"{p}:{i}" for p in readers for i, line in enumerate(p.read_text().splitlines(), 1)
             if pattern.search(line)]
    assert not found
