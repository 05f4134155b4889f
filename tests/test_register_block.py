"""RegisterBlock (decoders.generic.block): the compact points of unnamed registers are the same
points, the same JSON and the same summary as the dicts GenericModbus.make_points builds."""

from __future__ import annotations

import random
from pathlib import Path

import orjson
import pytest

from decoders.base import UnitState
from decoders.generic import GenericModbus
from decoders.generic.block import RegisterBlock
from decoders.generic.decoder import points_summary
from sniffer.frame import Frame
from sniffer.formats.records import frame_json, frame_record
from sniffer.capture.session import CaptureSpec, decode_capture
from sniffer.tui.framepack import pack, unpack

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
SPACES = ("holding", "input", "coil", "discrete")


def _random_blocks(n: int):
    rng = random.Random(9)
    for _ in range(n):
        space = rng.choice(SPACES)
        count = rng.choice((0, 1, 2, 7, 8, 9, 16, 125, rng.randint(1, 300)))
        top = 1 if space in ("coil", "discrete") else 0xFFFF
        values = [rng.randint(0, top) for _ in range(count)]
        yield space, rng.randint(0, 0xFFFF - count), values, rng.choice((3, 7, 11))


def test_block_points_json_and_summary_equal_the_dicts():
    generic, state = GenericModbus(), UnitState(1)
    for space, addr, values, offset in _random_blocks(400):
        want = generic.make_points(space, addr, values, state, offset)
        block = RegisterBlock(space, addr, values, offset)
        assert block.points() == want
        assert orjson.loads(block.json()) == want
        assert block.json() == orjson.dumps(want)  # byte for byte: the same key order and spacing
        for limit in (1, 6, 200):
            assert block.summary(limit) == points_summary(want, limit)


def test_repeated_and_changed_values_never_get_stale_text():
    """A block's shape remembers the last values' JSON and summary: each call still fits its values."""
    generic, state = GenericModbus(), UnitState(1)
    rng = random.Random(3)
    seq = [[1, 2, 3, 4, 5, 6, 7, 8], [1, 2, 3, 4, 5, 6, 7, 9], [9, 2, 3, 4, 5, 6, 7, 8]]
    for _ in range(300):
        values = list(rng.choice(seq))
        want = generic.make_points("holding", 40, values, state, 3)
        block = RegisterBlock("holding", 40, values, 3)
        order = ["json", "summary"] * 2
        rng.shuffle(order)
        for call in order:
            if call == "json":
                assert block.json() == orjson.dumps(want)
            else:
                assert block.summary() == points_summary(want)


def test_a_model_hook_gets_dicts_not_blocks():
    class Named(GenericModbus):
        def point(self, space, address, raw, state):
            return {"name": f"R{address}", "address": address, "raw": raw, "value": raw * 0.1, "unit": "Hz"}

    assert GenericModbus()._points("holding", 5, [1, 2], UnitState(1), 3).__class__ is RegisterBlock
    pts = Named()._points("holding", 5, [1, 2], UnitState(1), 3)
    assert pts == [{"name": "R5", "address": 5, "raw": 1, "value": 0.1, "unit": "Hz", "span": [3, 5]},
                   {"name": "R6", "address": 6, "raw": 2, "value": 0.2, "unit": "Hz", "span": [5, 7]}]


def test_frame_points_become_dicts_when_read_and_survive_the_tui_store():
    f = Frame(0, 0, 1, b"\x01\x03\x04\x00\x07\x00\x09", "modbus-rtu", 1, 3)
    f.points = RegisterBlock("holding", 100, [7, 9], 3)
    encoded = frame_json(f, 0)
    assert type(f._points) is RegisterBlock  # writing the JSON built no dicts
    assert f.points == [
        {"name": "holding[100]", "address": 100, "raw": 7, "value": 7, "unit": None, "span": [3, 5]},
        {"name": "holding[101]", "address": 101, "raw": 9, "value": 9, "unit": None, "span": [5, 7]},
    ]
    assert type(f._points) is list and f.points is f.points  # built once
    assert orjson.loads(encoded)["points"] == f.points
    f2 = Frame(0, 0, 1, b"\x01", "modbus-rtu", 1, 3)
    f2.points = RegisterBlock("coil", 0, [1, 0, 1], 3)
    assert unpack(pack(f2)).points == RegisterBlock("coil", 0, [1, 0, 1], 3).points()


def test_the_tui_store_keeps_a_block_as_its_values():
    """A sealed frame's block is marshalled as its values, never as 125 point dicts, and comes back a block."""
    f = Frame(0, 0, 1, b"\x01\x03\x04\x00\x07\x00\x09", "modbus-rtu", 1, 3)
    f.points = RegisterBlock("holding", 100, [7, 9], 3)
    packed = pack(f)
    assert type(f._points) is RegisterBlock  # packing built no dicts
    assert ("holding", 100, [7, 9], 3) in packed and not any(type(x) is RegisterBlock for x in packed)
    back = unpack(packed)
    assert type(back._points) is RegisterBlock and back.points == f.points and frame_json(back, 0) == frame_json(f, 0)


@pytest.mark.parametrize("capture", ["sim/default.mcap", "sim/errors.mcap", "sim/a510-ascii.mcap",
                                     "sim/tds-v8.mcap"])
def test_frame_json_is_the_json_of_frame_record(capture):
    """frame_json (msgspec, blocks joined from templates) against orjson of the record's dicts."""
    blocks = 0
    for f in decode_capture(CAPTURES / capture, CaptureSpec()):
        blocks += type(f._points) is RegisterBlock
        encoded = frame_json(f, 123)  # first: the record below turns a block into dicts
        assert orjson.loads(encoded) == orjson.loads(orjson.dumps(frame_record(f, 123)))
    if capture in ("sim/default.mcap", "sim/errors.mcap"):
        assert blocks > 100  # the generic decoder's blocks were written through their templates
