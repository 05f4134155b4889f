"""One line on stderr: `sniffer: TEXT`; and the "did you mean" of an error line about a mistyped name.

Written in one write and flushed: the capture's thread, the status watchdog, the MQTT client and the
--on-trigger runner all report from threads of their own, and print's two writes (the text, then the
newline) let another thread's line land inside one.
"""

from __future__ import annotations

import sys


def say(text: str) -> None:
    sys.stderr.write(f"sniffer: {text}\n")
    sys.stderr.flush()


def did_you_mean(word: str, known) -> str:
    """"; did you mean 'x'?" for the known name closest to a mistyped `word` (difflib), or "" if none is close.
    Said at the end of the one error line of a mistyped command, flag, model, scenario or fault."""
    import difflib

    if not isinstance(word, str) or not word:
        return ""
    names = [str(k) for k in known]
    close = difflib.get_close_matches(word, names, n=1, cutoff=0.6)
    if not close:  # a different case or a missing separator ("A510", "tdsv8")
        folded = {n.lower().replace("-", "").replace("_", ""): n for n in names}
        close = difflib.get_close_matches(word.lower().replace("-", "").replace("_", ""), list(folded), n=1,
                                          cutoff=0.75)
        close = [folded[c] for c in close]
    return f"; did you mean '{close[0]}'?" if close and close[0] != word else ""
