"""Capture triggers: `--trigger EXPR` keeps the minutes around each event as a window file of its own.

    sniffer live /dev/ttyUSB0 --trigger fault --trigger 'rate(crc) > 5/min' --pre 5m --post 1m --ring \\
        --out cab3.mcap --on-trigger 'scp "$SNIFFER_TRIGGER_FILE" ops@host:windows/'

Rules are filters of the TUI's language (sniffer.filterlang, with `rate()`); options.py checks
the flags (TriggerSpec), plan.py decides when windows open, grow and close (sans-I/O),
ring.py keeps the last `pre` of the capture compactly, window.py writes a window as a
replayable MCAP with its trigger in the metadata, command.py runs `--on-trigger`, sink.py joins
them as a sink the session adds (`trigger_sink`).  Every command that runs a capture session
takes them: live, demo, replay (and serve, for its capture process).
"""

from __future__ import annotations

import os

from sniffer.formats.outputs import FOLDER_MODE, OutputError, shown
from sniffer.triggers.options import TriggerSpec
from sniffer.triggers.window import read_trigger
from sniffer.formats import stem_of

_SETTLE_MARGIN_NS = 500_000_000


def windows_place(spec) -> tuple[str, str]:
    """(folder, stem) of a capture's window files: `--windows DIR` or the folder of --out (else here),
    named after --out, else the input file, else the port; OutputError for a folder that cannot be used."""
    t = spec.trigger
    named = spec.out or spec.input or (os.path.basename(spec.port) if spec.port else "") or "sniffer"
    stem = stem_of(named)
    folder = t.windows or (os.path.dirname(spec.out) if spec.out else "") or "."
    if t.windows and not os.path.exists(folder) and os.path.isdir(os.path.dirname(os.path.abspath(folder))):
        try:  # a new folder for the windows, as --rotate makes its own (not a whole missing path: a typo)
            os.mkdir(folder, FOLDER_MODE)
        except OSError as e:
            raise OutputError(f"--windows {shown(folder)}: cannot create the folder ({e.strerror})") from None
    if not os.path.isdir(folder):
        raise OutputError(f"--windows {shown(folder)}: not a folder")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"--windows {shown(folder)}: folder is not writable")
    return folder, stem or "sniffer"


def trigger_sink(spec, resolved, registry):
    """The session's trigger sink for `spec.trigger` (see sink.py)."""
    from sniffer.filterlang import register_ids
    from sniffer.triggers.sink import TriggerSink

    folder, stem = windows_place(spec)
    timeout = max([resolved.timeout_ms, *resolved.unit_timeouts.values()])
    return TriggerSink(spec.trigger, folder, stem, ids=register_ids(registry), char_ns=resolved.line.char_ns,
                       settle_ns=int(timeout * 1e6) + _SETTLE_MARGIN_NS)


__all__ = ["TriggerSpec", "read_trigger", "trigger_sink", "windows_place"]
