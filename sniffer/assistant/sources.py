"""What `sniffer mcp` was given, sorted once: capture files or rotated captures' folders, fleet datasets, the
sockets of live captures.  The assistant names a source by its name here and can reach nothing else: no path it
makes up is ever opened.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass

from sniffer.dataset.layout import META
from sniffer.events import CaptureError

CAPTURE, DATASET, SOCKET = "capture", "dataset", "socket"


@dataclass(frozen=True)
class Source:
    name: str  # what the assistant passes back: the argument as given
    kind: str  # CAPTURE, DATASET or SOCKET
    path: str  # the file, folder or socket address


def kind_of(arg: str) -> str:
    """CAPTURE, DATASET or SOCKET for one argument; CaptureError (one line) for a path that is none of them."""
    if arg.startswith("tcp:"):
        return SOCKET
    try:
        st = os.stat(arg)
    except OSError:
        raise CaptureError(f"{arg}: no such file, folder or socket") from None
    if stat.S_ISSOCK(st.st_mode):
        return SOCKET
    if stat.S_ISDIR(st.st_mode):
        return DATASET if os.path.isfile(os.path.join(arg, META)) else CAPTURE  # else a rotated capture's folder
    if stat.S_ISREG(st.st_mode):
        return CAPTURE
    raise CaptureError(f"{arg}: not a capture, a dataset's folder or a capture's socket")


def given(args: list[str]) -> dict[str, Source]:
    """{name: Source} of the command line's arguments, in their order (a name given twice counts once)."""
    return {a: Source(a, kind_of(a), a) for a in dict.fromkeys(args)}


def pick(given: dict[str, Source], name: str | None, kind: str) -> Source:
    """The source named `name` (or the only one of `kind` when no name is given); ValueError naming the ones
    there are, for the assistant to choose from."""
    of_kind = [s for s in given.values() if s.kind == kind]
    if not name:
        if len(of_kind) == 1:
            return of_kind[0]
        names = ", ".join(s.name for s in of_kind) or "none was given to sniffer mcp"
        raise ValueError(f"name the {kind} (one of: {names})")
    s = given.get(name) or next((s for s in of_kind if os.path.basename(s.name.rstrip("/")) == name), None)
    if s is None or s.kind != kind:
        names = ", ".join(s.name for s in of_kind) or "none was given to sniffer mcp"
        raise ValueError(f"{name[:80]!r} is not a {kind} this server was given (its {kind}s: {names})")
    return s
