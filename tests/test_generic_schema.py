"""The struct fast path reads exactly what the construct schema reads."""

from __future__ import annotations

from construct import Compiled, ConstructError
from hypothesis import given, settings
from hypothesis import strategies as st
from refdata import vector_rows

from decoders.generic.fast import FAST
from decoders.generic.schema import LAYOUTS

from helpers import bursts, run_events
from sniffer.line import LineSettings


def _construct(key, body):
    try:
        return dict(LAYOUTS[key].parse(body))
    except (ConstructError, ValueError, IndexError):
        return None


def _norm(d):
    if d is None:
        return None
    return {k: (list(v) if isinstance(v, list) else v) for k, v in d.items() if not k.startswith("_")}


def test_layouts_compile_but_compiled_bytes_is_lenient():
    """Why schema.py parses interpreted: compiled Bytes(this.n) does not notice a short body."""
    key = (0x02, "response")
    assert isinstance(LAYOUTS[key].compile(), Compiled)  # no lambdas: compilable
    assert LAYOUTS[key].compile().parse(b"\x02\x01")["status"] == b"\x01"  # silently short
    assert _construct(key, b"\x02\x01") is None  # interpreted: StreamError


@settings(max_examples=400, deadline=None)
@given(st.sampled_from(sorted(FAST)), st.binary(max_size=40))
def test_fast_equals_construct_on_random_bodies(key, body):
    fast = FAST[key](body)
    ref = _construct(key, body)
    if ref is None:
        assert fast is None
    else:
        assert _norm(fast) == _norm(ref)


def test_fast_equals_construct_on_vectors():
    line = LineSettings(19200)
    checked = 0
    for row in vector_rows():
        hexes = [row["request_hex"]] + ([row["response_hex"]] if row["response_hex"] else [])
        for f in run_events(bursts(hexes, line), line):
            key = (f.function, f.role)
            if f.crc_ok and key in FAST:
                body = f.raw[2:-2]
                assert _norm(FAST[key](body)) == _norm(_construct(key, body)), f.raw.hex()
                checked += 1
    assert checked > 150


def test_every_named_function_has_a_layout_both_ways():
    """The decoder takes its (function, role) table from names.py and the layouts from schema.py."""
    from decoders.generic.names import FUNCTION_NAMES

    assert set(LAYOUTS) == {(fc, role) for fc in FUNCTION_NAMES for role in ("request", "response")}


def test_decoders_load_without_construct_until_a_layout_is_needed():
    """construct costs 8 MB of RSS: common Modbus traffic never imports it; PD traffic and rare
    function codes do, on their first frame."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from decoders.registry import default_registry\n"
        "from sniffer.frame import Frame\n"
        "r = default_registry()\n"
        "f = Frame(0, 0, 1, bytes.fromhex('010300000001840a'), 'modbus-rtu', 1, 3, 1, True)\n"
        "f.adu, f.role = f.raw[:-2], 'request'\n"
        "r.decode(f)\n"
        "assert 'construct' not in sys.modules, 'common traffic imported construct'\n"
        "g = Frame(1, 0, 1, bytes.fromhex('01160001ff000000aaaa'), 'modbus-rtu', 1, 0x16, 1, True)\n"
        "g.adu, g.role = g.raw[:-2], 'request'\n"
        "r.decode(g)\n"
        "assert 'construct' in sys.modules and 'mask write' in g.summary, g.summary\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
