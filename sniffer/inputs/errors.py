"""InputError: an input (a file, an address) that breaks a rule of sniffer.inputs."""

from __future__ import annotations

from sniffer.events import CaptureError


class InputError(CaptureError):
    """An input that cannot be used, said in one line (exit 2): a CaptureError, so every reader's callers that
    already turn a CaptureError into one line do so for it too."""
