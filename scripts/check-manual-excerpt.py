#!/usr/bin/env python3
"""Hold tests/data/pd-series-manual-lines.json against the PD-series manual it was copied from.

    python scripts/check-manual-excerpt.py PATH/TO/pd-series-protocol.txt

The tests read only the copy (nothing outside the repository); run this by hand when the manual
changes.  Exit 0: every copied line and the file's hash match; 1: what differs, one line each.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

EXCERPT = Path(__file__).resolve().parent.parent / "tests" / "data" / "pd-series-manual-lines.json"


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    excerpt = json.loads(EXCERPT.read_text("utf-8"))
    raw = Path(argv[0]).read_bytes()
    text = raw.decode("utf-8").splitlines()
    problems = []
    if len(text) != excerpt["source_lines"]:
        problems.append(f"{len(text)} lines, the copy says {excerpt['source_lines']}")
    problems += [f"line {n} differs" for n, line in excerpt["lines"].items()
                 if int(n) > len(text) or text[int(n) - 1] != line]
    if hashlib.sha256(raw).hexdigest() != excerpt["source_sha256"]:
        problems.append("the manual changed since the excerpt was taken: re-check the lines and the hash")
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
