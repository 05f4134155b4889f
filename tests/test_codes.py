"""The code book: every annotation code is declared once, beside the stage that emits it, and the book is
assembled from those declarations (a framer's `codes`, a decoder class's `codes`, the core stages')."""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

from decoders.generic import GenericModbus
from decoders.registry import builtin_decoders, code_book, default_registry
from sniffer import codes, protocols
from sniffer.framing.ascii import AsciiFramer
from sniffer.framing.rtu import RtuFramer

ROOT = Path(__file__).resolve().parents[1]


def _declared_in_tree() -> list[tuple[str, str]]:
    """(code, file) for every `Code("...", ...)` written in sniffer/ and decoders/."""
    out = []
    for top in ("sniffer", "decoders"):
        for path in sorted((ROOT / top).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            if "Code(" not in text:
                continue
            for node in ast.walk(ast.parse(text)):
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "Code"
                        and node.args and isinstance(node.args[0], ast.Constant)):
                    out.append((node.args[0].value, str(path.relative_to(ROOT))))
    return out


def test_every_code_declared_in_the_tree_is_in_the_code_book():
    declared = _declared_in_tree()
    assert len(declared) > 50  # the walk found the declarations
    book = code_book()
    missing = [f"{code} ({where})" for code, where in declared if code not in book]
    assert missing == [], "declared, but claimed by no stage's `codes`: the code book does not have it"
    twice = [code for code, n in Counter(code for code, _ in declared).items() if n > 1]
    assert twice == [], "declared in two places"
    assert {c.code for c in book.all()} == {code for code, _ in declared}


def test_codes_are_well_formed():
    for c in code_book().all():
        assert c.severity in codes.SEVERITIES
        assert c.category is None or c.category in codes.CATEGORIES, c
        assert c.code == c.code.lower() and "." in c.code and " " not in c.code
        assert c.text


def test_sniffer_codes_declares_only_the_core_stages_codes():
    """A protocol's or a drive model's own codes (pd.*, tds.*, a510.*, a map's model.* checks) are declared
    beside its framer or decoder; sniffer/codes.py keeps what the core stages emit: the pipeline, pairer and
    registry, the Modbus framers and the generic Modbus decoder."""
    core = {c.code for c in (*codes.CORE_CODES, *RtuFramer.codes, *AsciiFramer.codes, *GenericModbus.codes)}
    here = {v.code for v in vars(codes).values() if isinstance(v, codes.Code)}
    assert here - core == set(), "declared in sniffer/codes.py, emitted by no core stage"


def test_each_decoder_declares_its_codes_on_its_class():
    """The book is read from the classes (no map loaded): what a loaded decoder claims is what its class
    declares."""
    for model, d in builtin_decoders().items():
        assert d.codes == type(d).codes, model


def test_the_views_code_book_holds_what_every_pipeline_may_emit():
    """Views that read records (no decoder at hand) ask `code_book()` what a code counts as: it must hold every
    code a registry's decoders and framers may emit, declared the same way."""
    book = code_book()
    reg = default_registry(model_files=[str(ROOT / "decoders" / "synplus_spl" / "registers.toml")])
    for c in reg.codebook.all():
        assert book.get(c.code) == c, c.code
    for cat in codes.CATEGORIES:
        assert book.in_category(cat) == {c.code for c in book.all() if c.category == cat}


def test_the_registry_code_book_holds_every_framer_code():
    book = default_registry().codebook
    for p in protocols.PROTOCOLS.values():
        for c in p.codes:
            assert c.code in book, f"{p.name} emits {c.code}, missing from the code book"
    assert "modbus.ascii.no_crlf" in book and "modbus.ascii.bad_hex" in book
