"""Golden decodes: every capture in captures/manifest.toml replays to its stored text.

`UPDATE_GOLDEN=1 pytest tests/test_golden.py` rewrites the goldens; review the
diff (a changed golden is a changed verdict), never accept it blindly.
"""

from __future__ import annotations

import contextlib
import io
import os
import tomllib
from pathlib import Path

import pytest

from sniffer.cli import main

CAPTURES = Path(__file__).resolve().parent.parent / "captures"
MANIFEST = tomllib.loads((CAPTURES / "manifest.toml").read_text())["capture"]


def _decode(entry) -> str:
    out = io.StringIO()
    err = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["replay", str(CAPTURES / entry["file"]), *entry["flags"]])
    assert rc == 0, err.getvalue()
    return out.getvalue()


def test_manifest_lists_every_capture_file():
    listed = {(CAPTURES / e["file"]).resolve() for e in MANIFEST}
    on_disk = {p.resolve() for p in (CAPTURES / "sim").glob("*.mcap")}
    assert on_disk <= listed
    assert all((CAPTURES / e["file"]).exists() for e in MANIFEST)
    assert all(e.get("about") for e in MANIFEST)


@pytest.mark.parametrize("entry", MANIFEST, ids=lambda e: e["name"])
def test_golden(entry):
    text = _decode(entry)
    golden = CAPTURES / "golden" / f"{entry['name']}.txt"
    if os.environ.get("UPDATE_GOLDEN"):
        golden.write_text(text)
    assert golden.exists(), f"no golden for {entry['name']}: run UPDATE_GOLDEN=1 pytest {__file__}"
    assert text == golden.read_text()
