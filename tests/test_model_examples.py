"""Every example frame printed in the manuals is a test vector.

decoders/<model>/examples.toml holds the bytes exactly as printed, with the
CRC verdict computed from them.  Where the manual's bytes are wrong the
sniffer must flag exactly that: a CRC mismatch with the expected CRC, or
(too short to be a frame) noise.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from helpers import bursts, run_events
from decoders.registry import builtin_decoders
from sniffer.line import LineSettings

ROOT = Path(__file__).resolve().parent.parent / "decoders"
LINE = LineSettings(9600, "N", 2)
MODELS = {Path(d.map.path).parent.name: mid for mid, d in builtin_decoders().items()
          if hasattr(d, "map") and not mid.endswith("-hf")}


def _examples():
    out = []
    for pkg, model in sorted(MODELS.items()):
        f = ROOT / pkg / "examples.toml"
        for ex in tomllib.loads(f.read_text())["examples"]:
            if ex.get("protocol", "modbus-rtu") == "modbus-rtu" and "hex" in ex:
                out.append((model, ex))
    return out


EXAMPLES = _examples()


def test_every_model_has_examples():
    assert {m for m, _ in EXAMPLES} == set(MODELS.values())
    assert len(EXAMPLES) >= 20


@pytest.mark.parametrize("model,ex", EXAMPLES, ids=lambda v: v if isinstance(v, str) else f"l{v['line']}")
def test_manual_example_frame(model, ex):
    data = bytes.fromhex(ex["hex"])
    unit = data[0] if data else 1
    frames = run_events(bursts([ex["hex"]], LINE), LINE, devices={unit: model})
    assert b"".join(f.raw for f in frames) == data
    if ex["crc_ok"]:
        assert len(frames) == 1
        f = frames[0]
        assert f.crc_ok and f.model == model
        assert not [a for a in f.annotations if a.severity == "error"], [(a.code, a.detail) for a in f.annotations]
        assert f.summary
    else:
        f = frames[0]
        if f.is_noise:
            assert len(data) < 4, "a wrong frame long enough to be one must be shown as a frame"
        else:
            assert f.crc_ok is False
            want = bytes.fromhex(ex["expected_crc"])
            got = bytes((f.crc_expected & 0xFF, f.crc_expected >> 8))
            assert got == want, f"expected CRC {want.hex()} (manual says so), we say {got.hex()}"


def _ascii_examples():
    out = []
    for pkg, model in sorted(MODELS.items()):
        for ex in tomllib.loads((ROOT / pkg / "examples.toml").read_text())["examples"]:
            if ex.get("protocol") == "modbus-ascii" and "ascii" in ex:
                out.append((model, ex))
    return out


ASCII_EXAMPLES = _ascii_examples()


@pytest.mark.parametrize("model,ex", ASCII_EXAMPLES, ids=lambda v: v if isinstance(v, str) else f"l{v['line']}")
def test_manual_ascii_example_frame(model, ex):
    """Modbus ASCII examples: a bad (or missing) LRC is flagged like a bad CRC."""
    from sniffer.events import Chunk

    wire = ex["ascii"].encode("latin-1")
    times = tuple(i * LINE.char_ns for i in range(len(wire)))
    frames = run_events([Chunk(0, wire, times)], LINE, devices={1: model, 2: model}, protocol="modbus-ascii")
    assert b"".join(f.raw for f in frames) == wire
    real = [f for f in frames if not f.is_noise]
    if ex["crc_ok"] and ex.get("bytes_ok", True):
        assert len(real) == 1 and real[0].crc_ok, [(f.raw, f.annotations) for f in frames]
        assert real[0].model == model and real[0].summary
    else:
        assert all(f.crc_ok is not True for f in frames), [(f.raw, f.crc_ok) for f in frames]
        flagged = [a for f in frames for a in f.annotations if a.severity in ("warning", "error")]
        assert flagged
        got = [f for f in real if f.crc_expected is not None]
        # where the manual's bytes themselves are wrong (bytes_ok = false, e.g. no LRC
        # at all) the expected LRC depends on the reading: compare only clean cases
        if got and "expected_crc" in ex and len(ex["expected_crc"]) == 2 and ex.get("bytes_ok", True):
            assert got[0].crc_expected == int(ex["expected_crc"], 16)


def test_ascii_examples_exist():
    assert len(ASCII_EXAMPLES) >= 10
