"""What the seeded fuzz tests share (test_input_fuzz.py, test_surface_fuzz.py): the seed, byte mutations,
a bound on each case's time, and the check of one run at the command line.

Deterministic: the same cases on every run; SNIFFER_FUZZ_SEED and SNIFFER_FUZZ_CASES explore others
locally.  The fuzz tests are marked `slow` (`-m "not slow"` leaves them out).
"""

from __future__ import annotations

import os
import random
import signal
from contextlib import contextmanager

from sniffer.cli import main

SEED = int(os.environ.get("SNIFFER_FUZZ_SEED", "20240611"))
CASES = int(os.environ.get("SNIFFER_FUZZ_CASES", "30"))
CASE_S = 60.0  # one case taking longer is a hang, not a slow machine


class Hang(BaseException):
    """A case ran past CASE_S (a BaseException: the CLI's own `except Exception` does not swallow it)."""


@contextmanager
def bounded(seconds: float = CASE_S, what: str = ""):
    """Raise Hang in the main thread if the block runs longer than `seconds`."""
    def alarm(signum, frame):
        raise Hang(f"hung for {seconds:.0f} s: {what}"[:300])

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def mutate(data: bytes, rng: random.Random) -> bytes:
    """Bit flips, a cut, a deleted / inserted / overwritten / repeated span."""
    d = bytearray(data)
    kind = rng.randrange(6)
    i = rng.randrange(len(d))
    n = rng.randint(1, 300)
    if kind == 0:
        for _ in range(rng.randint(1, 6)):
            d[rng.randrange(len(d))] ^= 1 << rng.randrange(8)
    elif kind == 1:
        del d[i:]
    elif kind == 2:
        del d[i:i + n]
    elif kind == 3:
        d[i:i] = rng.randbytes(n)
    elif kind == 4:
        d[i:i + n] = rng.randbytes(min(n, len(d) - i))
    else:
        j = rng.randrange(len(d))
        d[j:j] = d[i:i + n]
    return bytes(d)


def run(capsys, args, codes=(0, 2), warnings: int | None = None) -> tuple[int, list[str]]:
    """main(args) in bounded time: no traceback, an exit code of `codes`; exit 2 is one line
    "sniffer: error: ..."; otherwise every stderr line is the sniffer's (at most `warnings` of them)."""
    args = [str(a) for a in args]
    with bounded(what=" ".join(args)[:200]):
        code = main(args)
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err, err[-2000:]
    lines = [line for line in err.splitlines() if line.strip()]
    assert code in codes, (code, args[:6], lines[-3:])
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("sniffer: error: "), (args[:6], lines[-5:])
    else:
        assert all(line.startswith("sniffer: ") for line in lines), (args[:6], lines[-5:])
        if warnings is not None:
            assert len(lines) <= warnings, (args[:6], lines)
    return code, lines
