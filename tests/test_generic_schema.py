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
