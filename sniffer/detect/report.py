"""What `sniffer detect` prints and writes: the verdict, the ranked table, the units seen, the bus file."""

from __future__ import annotations

from sniffer.capture.busfile import BusFile, format_bus_file
from sniffer.detect.candidates import TWINS, fmt_of
from sniffer.detect.evidence import Evidence
from sniffer.detect.search import Verdict, rank

HEADER = ("setting", "protocol", "listened", "bytes", "UART errors", "fit frames", "pairs", "in pairs", "char time",
          "verdict")


def headline(v: Verdict, port: str) -> str:
    """One line: the line's settings and how sure, or why there are none."""
    n, secs = len(v.windows), sum(w.seconds for w in v.windows)
    if v.status == "no traffic":
        return (f"no traffic on {port}: nothing received in {secs:.0f} s (is the adapter on the bus, "
                f"A and B connected, the line polled?)")
    if v.status == "none":
        b = v.best
        return (f"no candidate fits: {n} settings tried in {secs:.1f} s, none gave request/response pairs with "
                f"good CRCs and (nearly) no UART errors; the closest, {_setting(b)}, had {_errors(b)} UART errors "
                f"and {b.best.fit_frames if b.best else 0} fitting frames")
    if v.status == "several":
        fitting = ", ".join(f"{_setting(r)} {r.best.protocol}" for r in (v.best, *v.rivals))
        return f"several candidates fit and nothing tells them apart: {fitting}"
    b = v.best
    what = f"{_line(b)} {b.best.protocol}"
    if v.status == "certain":
        return f"{what} (certain: {evidence(b)})"
    if v.status == "stop bits":
        twin = TWINS[b.fmt]
        return (f"{what} ({evidence(b)}; stop bits not told apart: a UART receives {b.fmt} and {twin} alike and "
                f"the characters' spacing could not be measured; either works for listening)")
    return f"{what} (fits, not certain: {'; '.join(b.doubts())}; {evidence(b)})"


def evidence(ev: Evidence) -> str:
    b = ev.best
    timing = f", characters {ev.bits_per_char:.1f} bits apart" if ev.bits_per_char is not None else ""
    if ev.line != ev.rx:
        timing += f" ({ev.line.bits_per_char} bits: {fmt_of(ev.line)}, received alike at {ev.fmt})"
    return (f"{b.fit_frames} frames with a good {'LRC' if b.protocol.endswith('ascii') else 'CRC'} fit {b.protocol}, "
            f"{b.pairs} request/response pairs, {_errors(ev)} UART errors in {ev.chars} bytes{timing}")


def table(v: Verdict) -> list[str]:
    """The listens, best first, one row each."""
    rows = [HEADER] + [_row(w) for w in sorted(v.windows, key=rank, reverse=True)]
    widths = [max(len(r[i]) for r in rows) for i in range(len(HEADER))]
    right = {2, 3, 4, 5, 6, 7}
    return ["  ".join(c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()
            for r in rows]


def _row(w: Evidence) -> tuple[str, ...]:
    b = w.best
    bits = f"{w.bits_per_char:.1f} bits {w.timing}" if w.bits_per_char is not None else "-"
    return (_setting(w), b.protocol if b else "-", f"{w.seconds:.2f} s", str(w.chars), _errors(w),
            f"{b.fit_frames}/{b.frames}" if b else "0", str(b.pairs) if b else "0",
            f"{b.paired:.0%}" if b else "-", bits, verdict_word(w))


def verdict_word(w: Evidence) -> str:
    """A listen's verdict on its own setting, in a word or two."""
    if w.certain or w.fits:
        word = "certain" if w.certain else "fits"
        return word if w.line == w.rx else f"{word} as {fmt_of(w.line)}"
    if w.best is None:
        return "no frames"
    return "UART errors" if w.errors else "too fast" if w.timing == "impossible" else "does not fit"


def _setting(w: Evidence) -> str:
    return f"{w.rx.baud} {w.fmt}"


def _line(w: Evidence) -> str:
    """The settings the listen's evidence supports (its own, or its twin with the other stop bits)."""
    return f"{w.line.baud} {fmt_of(w.line)}"


def _errors(w: Evidence) -> str:
    return f"{w.errors} ({w.errors / w.chars:.0%})" if w.errors and w.chars else str(w.errors)


def units(ev: Evidence) -> list[str]:
    """The units that were polled, with their poll periods and functions."""
    return [u.describe(ev.seconds) for u in ev.units]


def bus_file(v: Verdict, port: str) -> str:
    """The bus file for the verdict's line (`sniffer live PORT --bus FILE`); the units seen as comments:
    a device map would turn off the guessing of their models."""
    ev = v.best
    line = ev.line
    bus = BusFile(line.baud, line.parity, line.stopbits, ev.best.protocol,
                  line.databits if line.databits != 8 else None)
    comments = [f"written by `sniffer detect {port}`: {headline(v, port)}"]
    trailer = ["units seen (name their models here, or leave them to be guessed from their answers):", "[units]"]
    trailer += [f'{u.unit} = "{_default_model(ev.best.protocol)}"   # {line}' for u, line in zip(ev.units, units(ev))]
    return format_bus_file(bus, comments, trailer if ev.units else [])


def link_table(v: Verdict, name: str, port: str) -> tuple[BusFile, list[str]]:
    """A settled port as one [[links]] table of a bus file (`sniffer detect P1 P2 --write-bus`), and the comment
    lines after it: the units seen, as a `units = {...}` to name their models in."""
    ev = v.best
    line = ev.line
    link = BusFile(line.baud, line.parity, line.stopbits, ev.best.protocol,
                   line.databits if line.databits != 8 else None, name=name, ports=(port,))
    notes = []
    if ev.units:
        model = _default_model(ev.best.protocol)
        notes = ["units seen (name their models here, or leave them to be guessed from their answers):",
                 "units = { " + ", ".join(f'{u.unit} = "{model}"' for u in ev.units) + " }"]
        notes += [f"  {text}" for text in units(ev)]
    return link, notes


def _default_model(protocol: str) -> str:
    from sniffer.protocols import get

    return get(protocol).default_model
