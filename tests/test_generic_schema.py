"""The construct layouts (schema.py): compilable, read interpreted, one for every named function both ways.

test_generic_inline holds the decoder's in-place readers equal to them."""

from __future__ import annotations

from construct import Compiled, ConstructError

from decoders.generic.schema import LAYOUTS



def _construct(key, body):
    try:
        return dict(LAYOUTS[key].parse(body))
    except (ConstructError, ValueError, IndexError):
        return None


def test_layouts_compile_but_compiled_bytes_is_lenient():
    """Why schema.py parses interpreted: compiled Bytes(this.n) does not notice a short body."""
    key = (0x02, "response")
    assert isinstance(LAYOUTS[key].compile(), Compiled)  # no lambdas: compilable
    assert LAYOUTS[key].compile().parse(b"\x02\x01")["status"] == b"\x01"  # silently short
    assert _construct(key, b"\x02\x01") is None  # interpreted: StreamError


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
