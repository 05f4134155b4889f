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


def units(ev: Evidence, named: dict | None = None) -> list[str]:
    """The units that were polled, with their poll periods and functions, and the model each was named."""
    return [u.describe(ev.seconds) + _model_words(u.unit, named) for u in ev.units]


def _model_words(unit: int, named: dict | None) -> str:
    if named is None or unit == 0:
        return ""
    n = named.get(unit)
    if n is None:
        return "; model not identified"
    return f"; {n.model} ({n.confidence:.0%}: {n.evidence})"


def unnamed_line(ev: Evidence, named: dict) -> str | None:
    """One line naming the units whose model the listen could not tell, or None."""
    left = [u.unit for u in ev.units if u.unit and u.unit not in named]
    if not left:
        return None
    return (f"model not identified for unit{'s' if len(left) > 1 else ''} {', '.join(map(str, left))} "
            f"(no answer only one model gives, yet): the bus file leaves {'them' if len(left) > 1 else 'it'} "
            f"commented (generic); listen longer (--identify-time) or name the model")


def bus_file(v: Verdict, port: str, named: dict | None = None) -> str:
    """The bus file for the verdict's line (`sniffer live PORT --bus FILE`): the units whose model was
    identified in [units]; the others as comments (a generic entry would stop their models being guessed)."""
    ev = v.best
    line = ev.line
    named = named or {}
    models = {u.unit: named[u.unit].model for u in ev.units if u.unit in named}
    bus = BusFile(line.baud, line.parity, line.stopbits, ev.best.protocol,
                  line.databits if line.databits != 8 else None, devices=models)
    comments = [f"written by `sniffer detect {port}`: {headline(v, port)}"]
    comments += [text for u, text in zip(ev.units, units(ev, named)) if u.unit in models]
    left = [(u, text) for u, text in zip(ev.units, units(ev, named)) if u.unit not in models]
    trailer = []
    if left:
        trailer = ["units seen whose model was not identified (name it here, or leave it to be guessed from "
                   "their answers):"]
        trailer += ([] if models else ["[units]"])
        trailer += [f'{u.unit} = "{_default_model(ev.best.protocol)}"   # {text}' for u, text in left]
    return format_bus_file(bus, comments, trailer)


def link_table(v: Verdict, name: str, port: str, named: dict | None = None) -> tuple[BusFile, list[str]]:
    """A settled port as one [[links]] table of a bus file (`sniffer detect P1 P2 --write-bus`), and the comment
    lines after it: the units identified in its `units = {...}`, the others as comments."""
    ev = v.best
    line = ev.line
    named = named or {}
    models = {u.unit: named[u.unit].model for u in ev.units if u.unit in named}
    link = BusFile(line.baud, line.parity, line.stopbits, ev.best.protocol,
                   line.databits if line.databits != 8 else None, name=name, ports=(port,), devices=models)
    notes = []
    left = [u for u in ev.units if u.unit not in models]
    if left:
        model = _default_model(ev.best.protocol)
        notes = ["units seen whose model was not identified (name it here, or leave it to be guessed):"]
        notes += ([f"units = {{ {', '.join(f'{u.unit} = {chr(34)}{model}{chr(34)}' for u in left)} }}"] if not models
                  else [f"add to units above: {', '.join(f'{u.unit} = {chr(34)}MODEL{chr(34)}' for u in left)}"])
    notes += [f"  {text}" for text in units(ev, named)]
    return link, notes


def _default_model(protocol: str) -> str:
    from sniffer.protocols import get

    return get(protocol).default_model
