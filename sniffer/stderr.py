"""One line on stderr: `sniffer: TEXT`.

Written in one write and flushed: the capture's thread, the status watchdog, the MQTT client and the
--on-trigger runner all report from threads of their own, and print's two writes (the text, then the
newline) let another thread's line land inside one.
"""

from __future__ import annotations

import sys


def say(text: str) -> None:
    sys.stderr.write(f"sniffer: {text}\n")
    sys.stderr.flush()
