"""The code book: every annotation code is declared once in sniffer/codes.py and claimed by a stage."""

from __future__ import annotations

from decoders.registry import builtin_decoders, default_registry
from sniffer import codes, protocols


def test_every_declared_code_is_claimed_by_a_stage():
    claimed = {c.code for c in codes.CORE_CODES} | {c.code for c in protocols.all_codes()}
    for d in builtin_decoders().values():
        claimed |= {c.code for c in d.codes}
    declared = {c.code for c in codes.ALL_CODES}
    assert declared - claimed == set(), "declared in codes.py, emitted by no stage"
    assert claimed - declared == set(), "claimed by a stage, not declared in codes.py"


def test_codes_are_unique_and_well_formed():
    seen = {}
    for c in codes.ALL_CODES:
        assert c.code not in seen, f"{c.code} declared twice"
        seen[c.code] = c
        assert c.severity in codes.SEVERITIES
        assert c.code == c.code.lower() and "." in c.code and " " not in c.code
        assert c.text


def test_the_registry_code_book_holds_every_framer_code():
    book = default_registry().codebook
    for p in protocols.PROTOCOLS.values():
        for c in p.codes:
            assert c.code in book, f"{p.name} emits {c.code}, missing from the code book"
    assert "modbus.ascii.no_crlf" in book and "modbus.ascii.bad_hex" in book
