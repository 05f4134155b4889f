"""Golden decodes: every capture in captures/manifest.toml passes `sniffer check` against its golden.

The goldens are `check`'s own format (v2: one line per frame, every point of it), so the project's
captures are held the way a user's are, and a value in the 20th register of a read is checked too.

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


def _check(entry, update: bool) -> tuple[int, str]:
    """`sniffer check` of the capture against its golden (the regression path the project ships)."""
    golden = CAPTURES / "golden" / f"{entry['name']}.txt"
    out = io.StringIO()
    err = io.StringIO()
    args = ["check", str(CAPTURES / entry["file"]), "--golden", str(golden), *entry["flags"]]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(args + (["--update-golden"] if update else []))
    return rc, out.getvalue() + err.getvalue()


def test_manifest_lists_every_capture_file():
    listed = {(CAPTURES / e["file"]).resolve() for e in MANIFEST}
    on_disk = {p.resolve() for p in (CAPTURES / "sim").glob("*.mcap")}
    assert on_disk <= listed
    assert all((CAPTURES / e["file"]).exists() for e in MANIFEST)
    assert all(e.get("about") for e in MANIFEST)


@pytest.mark.parametrize("entry", MANIFEST, ids=lambda e: e["name"])
def test_golden(entry):
    golden = CAPTURES / "golden" / f"{entry['name']}.txt"
    if os.environ.get("UPDATE_GOLDEN"):
        rc, text = _check(entry, update=True)
        assert rc == 0, text
    assert golden.exists(), f"no golden for {entry['name']}: run UPDATE_GOLDEN=1 pytest {__file__}"
    assert golden.read_text().startswith("# sniffer golden v2")  # every point, not only the summary's six
    rc, text = _check(entry, update=False)
    assert rc == 0, text
