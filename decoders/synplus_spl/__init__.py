"""Synplus SPL inverter (with built-in PLC): register map only; standard function codes."""

from pathlib import Path

from decoders.table_decoder import TableDecoder
from ..tables import load_map

MAP_PATH = Path(__file__).with_name("registers.toml")


def load() -> TableDecoder:
    return TableDecoder(load_map(MAP_PATH))
