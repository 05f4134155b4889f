"""What the tests of logic captures share: sigrok-cli or a reason, the public captures' channels, a decode."""

from __future__ import annotations

import os
import shutil

import pytest
from refdata import SIGROK, sigrok_line, sigrok_meta

from helpers import run_events
from sniffer.capture.pipeline import roles_of
from sniffer.sources.logic_options import LogicSpec

SR_NAMES = sorted(p.stem for p in SIGROK.glob("*.sr"))


def need_sigrok_cli() -> str:
    """sigrok-cli's path; without it the test fails on CI (CI=true: scripts/install-system-deps.sh installs it)
    and skips elsewhere."""
    path = shutil.which("sigrok-cli")
    if path is None:
        why = "sigrok-cli is not installed (apt-get install sigrok-cli; scripts/install-system-deps.sh)"
        if os.environ.get("CI"):
            pytest.fail(why)
        pytest.skip(why)
    return path


def ref_logic(name: str) -> LogicSpec:
    """The channels of a public capture as its JSON says: the line the slave receives (requests) is --rx, the
    one it answers on --tx; a half-duplex line (both directions) --rx alone."""
    m = sigrok_meta(name)
    line = sigrok_line(name)
    rx = tx = None
    for ch, d in m["channels"].items():
        if d["carries"].startswith(("client->server", "both")):
            rx = ch
        else:
            tx = ch
    return LogicSpec(rx, tx, invert=bool(m.get("line_inverted_in_capture")), baud=line.baud, parity=line.parity,
                     stopbits=line.stopbits)


def decode_source(src, line, **kw):
    """Frames of a sigrok source through the real pipeline, with the roles its capture info records."""
    info = src.open()
    return run_events(src.events(), line, info=info, directions=roles_of(info), **kw)
