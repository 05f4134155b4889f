"""`sniffer detect PORT`: find an unknown line's baud rate, format and protocol by listening only.

The port is opened read-only as `live` opens it; see sniffer/detect/ for how the
candidates are tried and judged.  Prints the verdict, the ranked table of what
was heard and the units seen; `--write-bus FILE` writes the bus file `live --bus`
takes.  Exit 0 when the line is settled, 1 when there was no traffic or no
candidate fits (one line on stderr; nothing is guessed, no file written), 2 for
bad flags or a port that cannot be opened.
"""

from __future__ import annotations

import sys

from ..detect.candidates import baud_order, parse_bauds, setting
from ..detect.evidence import Evidence
from ..detect.listen import SerialPort, listen
from ..detect.report import bus_file, headline, table, units, verdict_word
from ..detect.search import Search
from ..outputs import Output
from ..settings import CaptureSpec
from .common import EXIT_FAILED, EXIT_OK, UsageError, say


def cmd_detect(spec: CaptureSpec, args) -> int:
    bauds = baud_order(parse_bauds(args.bauds))
    if not (args.max_time > 0 and args.quiet_time > 0 and args.units_time >= 0):
        raise UsageError("--max-time and --quiet-time must be more than 0 seconds, --units-time 0 or more")
    out = Output(args.write_bus, inputs=[spec.port], what="--write-bus") if args.write_bus else None
    port = spec.port
    serial = SerialPort(port)
    serial.configure(setting(bauds[0], "8N1"))  # a port that cannot be opened: one line, before anything else
    if not args.quiet:
        say(f"listening on {port} (read-only, nothing is sent): up to {len(bauds)} baud rates, "
            f"at most {args.max_time:g} s")
    verdict = listen(serial, Search(bauds, quiet_s=args.quiet_time), max_s=args.max_time,
                     follow_s=args.units_time, on_window=None if args.quiet else _progress)
    line = headline(verdict, port)
    if verdict.status == "no traffic":
        say(f"error: {line}")
        return EXIT_FAILED
    print("\n".join(table(verdict)))
    if not verdict.settled:
        say(f"error: {line}")
        return EXIT_FAILED
    print(f"\nline: {line}")
    print(f"settled in {verdict.decided_s:.1f} s of listening ({len(verdict.windows)} settings)")
    seen = units(verdict.best)
    if seen:
        print("units seen:\n" + "\n".join(f"  {u}" for u in seen))
    if out is not None:
        try:
            with open(out.part, "w", encoding="utf-8") as f:
                f.write(bus_file(verdict, port))
            out.commit()
        except BaseException:
            out.discard()
            raise
        say(f"wrote {out.path}: sniffer live {port} --bus {out.path}")
    sys.stdout.flush()
    return EXIT_OK


def _progress(ev: Evidence) -> None:
    b = ev.best
    frames = f", {b.fit_frames} {b.protocol} frames fit, {b.pairs} pairs" if b else ""
    say(f"{ev.rx.baud} {ev.fmt} ({ev.seconds:.1f} s): {ev.chars} bytes, {ev.errors} UART errors{frames}: "
        f"{verdict_word(ev)}")
