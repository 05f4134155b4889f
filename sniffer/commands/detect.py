"""`sniffer detect PORT...`: find an unknown line's baud rate, format and protocol by listening only.

The port is opened read-only as `live` opens it; see sniffer/detect/ for how the
candidates are tried and judged.  Prints the verdict, the ranked table of what
was heard and the units seen; `--write-bus FILE` writes the bus file `live --bus`
takes.  Exit 0 when the line is settled, 1 when there was no traffic or no
candidate fits (one line on stderr; nothing is guessed, no file written), 2 for
bad flags or a port that cannot be opened.  Several ports are listened to at once
(a process each, sniffer/detect/ports.py), a report each; `--write-bus` then writes
one bus file with a [[links]] table per port that settled (named after its port,
the units seen as comments), exit 0 only when every port settled.
"""

from __future__ import annotations

import sys

from sniffer.detect.candidates import baud_order, parse_bauds, setting
from sniffer.detect.evidence import Evidence
from sniffer.detect.models import Naming
from sniffer.detect.report import bus_file, headline, table, units, unnamed_line, verdict_word
from sniffer.detect.search import Search
from sniffer.formats.outputs import Output
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_FAILED, EXIT_OK, UsageError, need_posix_tty, say
from sniffer.commands.flags import command_parser, duration, logic_flags

_DESCRIPTION = """\
    Listen to PORT (opened read-only: nothing is ever sent) at one setting after another and say which
    baud rate, character format and protocol the line runs, with the evidence: frames with a good
    CRC/LRC, request/response pairs, the UART's parity and framing errors (the tty marks them), and
    whether the characters come as fast as the format allows."""
_EPILOG = """\
    Tries 1200 ... 921600 baud (the common rates, most common first; --bauds adds others), 8N1 8E1 8O1
    8N2 (and 7E1 7O1 7N2 for ASCII lines), Modbus RTU, Modbus ASCII and the PD-series protocol, and
    stops as soon as one candidate is certain.

    Several ports are listened to at once; --write-bus writes one bus file with a [[links]] table for
    each port that settled (named after the port).

    exit status: 0 the line is settled (printed; written with --write-bus), 1 no traffic or no candidate
    fits (nothing is guessed, no file written; several ports: one did not settle), 2 bad flags or a
    port that cannot be opened."""


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "detect",
        help="find an unknown line's baud rate, parity, stop bits and protocol by listening (read-only)",
        description=_DESCRIPTION, epilog=_EPILOG,
        examples=["sniffer detect /dev/ttyUSB0 --write-bus line.toml",
                  "sniffer live /dev/ttyUSB0 --bus line.toml          # then capture with what it found",
                  "sniffer detect /dev/ttyUSB0 /dev/ttyUSB1 --write-bus plant.toml",
                  "sniffer detect line.sr --write-bus line.toml        # a logic analyzer's capture"])
    p.add_argument("ports", nargs="+", metavar="port",
                   help="serial device, e.g. /dev/ttyUSB0 (several: listened to at once, --write-bus writes a "
                        "[[links]] table each); or a logic capture: a sigrok .sr file, or a live analyzer "
                        "sigrok:DRIVER (bit widths from the samples: tells 8E1 from 8E2)")
    logic_flags(p, live=True)
    p.add_argument("--bauds", action="append", metavar="RATES",
                   help="more baud rates to try, first: 250000,31250 (repeatable)")
    p.add_argument("--write-bus", metavar="FILE.toml", help="write the line's settings as a bus file for live --bus")
    p.add_argument("--max-time", type=duration("--max-time", upper_s=86_400.0), default=60.0, metavar="TIME",
                   help="give up after this much listening: 60 (seconds), 5min (default 60 s)")
    p.add_argument("--quiet-time", type=duration("--quiet-time", upper_s=86_400.0), default=5.0, metavar="TIME",
                   help="no byte in the first TIME: no traffic (default 5 s)")
    p.add_argument("--units-time", type=duration("--units-time", upper_s=86_400.0), default=2.0, metavar="TIME",
                   help="once certain, listen this much more for the units and their poll periods (default 2 s)")
    p.add_argument("--identify-time", type=duration("--identify-time", upper_s=86_400.0), default=30.0,
                   metavar="TIME", help="once certain, listen up to this long until every unit's drive model is "
                                        "identified from its answers (default 30 s; 0: do not wait)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")


def run(spec: CaptureSpec, args) -> int:
    from sniffer.sources.logic_options import is_device
    from sniffer.sources.srzip import sniff

    logic = [p for p in args.ports if is_device(p) or sniff(p)]
    if len(args.ports) > 1:
        if logic:
            raise UsageError(f"{logic[0]}: a logic capture is detected alone (several ports: serial ports only)")
        need_posix_tty("detect (listening on a serial port)")
        return _detect_ports(spec, args)
    if logic:
        return _detect_logic(spec, args)
    if spec.logic is not None:
        raise UsageError(f"--rx is for a logic capture: a sigrok .sr file or sigrok:DRIVER, not {spec.port}")
    need_posix_tty("detect (listening on a serial port)")
    from sniffer.detect.listen import SerialPort, listen

    bauds = _bauds(args)
    out = Output(args.write_bus, inputs=spec.read_paths(), what="--write-bus") if args.write_bus else None
    port = spec.port
    serial = SerialPort(port)
    serial.configure(setting(bauds[0], "8N1"))  # a port that cannot be opened: one line, before anything else
    if not args.quiet:
        say(f"listening on {port} (read-only, nothing is sent): up to {len(bauds)} baud rates, "
            f"at most {args.max_time:g} s")
    naming = Naming(spec.model_files)
    verdict = listen(serial, Search(bauds, quiet_s=args.quiet_time), max_s=args.max_time,
                     follow_s=args.units_time, on_window=None if args.quiet else _progress,
                     more=naming.wants_more, more_s=args.identify_time)
    line = headline(verdict, port)
    if verdict.status == "no traffic":
        say(f"error: {line}")
        return EXIT_FAILED
    print("\n".join(table(verdict)))
    if not verdict.settled:
        say(f"error: {line}")
        return EXIT_FAILED
    print(f"\nline: {line}")
    more = sum(w.seconds for w in verdict.windows) - verdict.decided_s
    more = f", then {more:.1f} s more for the units and their models" if more >= 0.05 else ""
    print(f"settled in {verdict.decided_s:.1f} s of listening ({len(verdict.windows)} settings){more}")
    named = naming.feed(verdict.best.answers, verdict.best.best.protocol)
    seen = units(verdict.best, named)
    if seen:
        print("units seen:\n" + "\n".join(f"  {u}" for u in seen))
    left = unnamed_line(verdict.best, named)
    if left:
        say(f"note: {left}")
    if out is not None:
        try:
            out.write_text(bus_file(verdict, port, named))
            out.commit()
        except BaseException:
            out.discard()
            raise
        say(f"wrote {out.path}: sniffer live {port} --bus {out.path}")
    sys.stdout.flush()
    return EXIT_OK


def _bauds(args) -> tuple[int, ...]:
    """The rates to try (--bauds first), once the listening times are checked."""
    bauds = baud_order(parse_bauds(args.bauds))
    if not (args.max_time > 0 and args.quiet_time > 0 and args.units_time >= 0):
        raise UsageError("--max-time and --quiet-time must be more than 0 seconds, --units-time 0 or more")
    return bauds


def _detect_ports(spec: CaptureSpec, args) -> int:
    """`detect P1 P2 ...`: every port listened to at once (sniffer/detect/ports.py), a report each, and with
    --write-bus one bus file of a [[links]] table per port that settled.  Exit 0 when every port settled."""
    from sniffer.capture.busfile import format_links
    from sniffer.detect.listen import SerialPort, listen
    from sniffer.detect.ports import settle

    bauds = _bauds(args)
    out = Output(args.write_bus, inputs=spec.read_paths(), what="--write-bus") if args.write_bus else None
    names = _link_names([plan.name for plan in spec.links])
    opened = {}
    try:
        for name, port in zip(names, args.ports):  # a port that cannot be opened: one line, before any listening
            opened[name] = SerialPort(port)
            opened[name].configure(setting(bauds[0], "8N1"))
    except BaseException:
        for serial in opened.values():
            serial.close()
        raise
    if not args.quiet:
        say(f"listening on {len(opened)} ports at once (read-only, nothing is sent): up to {len(bauds)} baud rates "
            f"each, at most {args.max_time:g} s")

    def listen_one(serial):
        on_window = None if args.quiet else (lambda ev: _progress(ev, f"{serial.path}: "))
        naming = Naming(spec.model_files)
        return listen(serial, Search(bauds, quiet_s=args.quiet_time), max_s=args.max_time,
                      follow_s=args.units_time, on_window=on_window, more=naming.wants_more,
                      more_s=args.identify_time)

    results = settle(opened, listen_one)
    for r in results:
        print(f"{r.port} ({r.name}):")
        if r.table:
            print("\n".join(f"  {row}" for row in r.table))
        if r.settled:
            print(f"  line: {r.headline}")
            print(f"  settled in {r.decided_s:.1f} s of listening ({r.tried} settings)")
            if r.units:
                print("  units seen:\n" + "\n".join(f"    {u}" for u in r.units))
        print()
    sys.stdout.flush()
    settled = [r for r in results if r.settled]
    for r in results:
        if not r.settled:
            say(f"error: {r.headline}" if r.headline.startswith(r.port) else f"error: {r.port}: {r.headline}")
    if out is not None and settled:
        comments = [f"written by `sniffer detect {' '.join(args.ports)}`"]
        comments += [f"{r.name}: {r.headline}" if r.settled else f"{r.port}: not settled, not in this file "
                     f"({r.headline})" for r in results]
        try:
            out.write_text(format_links([r.link for r in settled], comments, [r.notes for r in settled]))
            out.commit()
        except BaseException:
            out.discard()
            raise
        left = len(results) - len(settled)
        missing = f" ({left} of the ports not in it: said above)" if left else ""
        say(f"wrote {out.path}: sniffer live --bus {out.path}{missing}")
    return EXIT_OK if len(settled) == len(results) else EXIT_FAILED


def _link_names(names: list[str]) -> list[str]:
    """The links' names (a port's file name: ttyUSB0) as a bus file takes them: a word, without , : or \"."""
    out = []
    for name in names:
        word = "".join("-" if c.isspace() or c in ',:"' else c for c in name) or "link"
        while word in out:
            word += "-2"
        out.append(word)
    return out


def _progress(ev: Evidence, prefix: str = "") -> None:
    b = ev.best
    frames = f", {b.fit_frames} {b.protocol} frames fit, {b.pairs} pairs" if b else ""
    say(f"{prefix}{ev.rx.baud} {ev.fmt} ({ev.seconds:.1f} s): {ev.chars} bytes, {ev.errors} UART errors{frames}: "
        f"{verdict_word(ev)}")


LIVE_LISTEN_S = 10.0  # a live analyzer is read this long (less with --max-time), once to measure, once to decode


def _detect_logic(spec: CaptureSpec, args) -> int:
    """`detect FILE.sr` / `detect sigrok:DRIVER`: bit widths from the samples, checked by sigrok's UART decode."""
    from sniffer.capture.busfile import BusFile, format_bus_file
    from sniffer.detect.logic import detect_logic, summary, table
    from sniffer.sources.logic_options import DeviceSpec, LogicSpec, is_device
    from sniffer.sources.sigrok_cli import DEFAULT_RATE, SigrokSource, device_channels, file_source
    from sniffer.sources.srzip import read_meta

    where = spec.port
    wanted = [spec.logic.rx] if spec.logic is not None else None
    out = Output(args.write_bus, inputs=[where], what="--write-bus") if args.write_bus else None
    if is_device(where):
        device = DeviceSpec.parse(where)
        channels = device_channels(device)
        rate = (spec.logic.samplerate if spec.logic else None) or DEFAULT_RATE
        seconds = min(args.max_time, LIVE_LISTEN_S)
        if seconds <= 0:
            raise UsageError("--max-time must be more than 0 seconds")
        common = ["-d", device.arg, "-c", f"samplerate={rate}", "--samples", str(int(rate * seconds))]
        chosen = wanted or channels[:8]
        missing = [c for c in chosen if c not in channels]
        if missing:
            raise UsageError(f"{where}: no logic channel {missing[0]!r} (channels: {', '.join(channels)})")

        def source_of(logic: LogicSpec):
            return SigrokSource(logic, where, [*common, "-C", logic.rx], rate, channels)

        acquire = [*common, "-C", ",".join(chosen)]
        if not args.quiet:
            say(f"reading {where} at {rate:,} samples/s for {seconds:g} s (nothing is sent), then decoding "
                f"{seconds:g} s more at the settings measured")
    else:
        meta = read_meta(where)
        rate, channels = meta.samplerate, list(meta.channels)
        chosen = wanted or channels[:8]
        for c in chosen:
            meta.bit(c)
        if not wanted and len(channels) > 8:
            say(f"note: {where} has {len(channels)} channels: measuring the first 8 (--rx CHANNEL for another)")

        def source_of(logic: LogicSpec):
            return file_source(where, logic)

        acquire = ["-i", where]
    verdicts = detect_logic(where, acquire, chosen, rate, source_of)
    print("\n".join(table(verdicts)))
    found = summary(verdicts, where)
    if found is None:
        say(f"error: {where}: no channel carries a UART line this could settle (see the table)")
        return EXIT_FAILED
    line, flags, serial = found
    print(f"\nline: {line}")
    command = "live" if is_device(where) else "replay"
    settled = next(c.measurement for c in verdicts if c.verdict == "settled")
    if settled.databits == 8:
        print(f"decode it: sniffer {command} {where} {' '.join(flags + serial)}")
    else:  # no flag says 7 data bits: a bus file does
        print(f"decode it: sniffer {command} {where} {' '.join(flags)} --bus FILE (--write-bus FILE writes it: "
              f"{settled.databits} data bits)")
    if out is not None:
        m = next(c.measurement for c in verdicts if c.verdict == "settled")
        from sniffer.detect.logic import protocol_of

        bus = BusFile(m.baud, m.parity, m.stopbits, protocol_of(m).name, m.databits if m.databits != 8 else None)
        text = format_bus_file(bus, [f"written by `sniffer detect {where}`: {line}",
                                     f"logic channels: {' '.join(flags)}"])
        try:
            with open(out.part, "w", encoding="utf-8") as f:
                f.write(text)
            out.commit()
        except BaseException:
            out.discard()
            raise
        say(f"wrote {out.path}: sniffer {command} {where} --bus {out.path} {' '.join(flags)}")
    sys.stdout.flush()
    return EXIT_OK
