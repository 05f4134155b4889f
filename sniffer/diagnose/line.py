"""wrong_line_settings: the capture was read at another baud rate, parity or stop bits than the line runs.

Two pictures, each with what to try:

* almost no byte is in a frame whose CRC holds (a wrong baud rate: what the UART makes of the line is
  noise and broken frames).  With per-byte times the line's own baud shows in the bursts: the master's
  most common request is 8 bytes, and the shortest common burst lasts about 8 of the line's
  characters (`_baud_from_bursts`: what a UART at the wrong baud makes of it lasts about as long); with
  per-read times only
  `sniffer detect` can tell;
* the frames' CRCs match but the UART flags many of their bytes (the baud is right, the character
  format is not; such a frame is not taken as good, its CRC is `modbus.crc.unproven`): parity errors
  on nearly every byte = the other parity (E <-> O); on some = the line has
  none; framing errors on some and no parity errors = the line has a parity bit where the sniffer
  expects the stop bit, and the flagged bytes' parity says which (a 0 parity bit fails the stop bit:
  under even parity that is a byte with an even number of ones).

Nothing else on a link is judged once its settings are wrong (Diagnosis.findings drops the rest).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sniffer.codes import CRC_UNPROVEN, UART_FRAMING, UART_PARITY
from sniffer.diagnose.codesets import UART
from sniffer.codes import ERROR
from sniffer.diagnose.state import Group, Link
from sniffer.diagnose.finding import Finding

if TYPE_CHECKING:
    from sniffer.diagnose.engine import Diagnosis

MIN_BYTES = 300
GOOD_SHARE = 0.3  # below: the bytes are not the line's frames
GOOD_FRAMES = 0.2  # ... and fewer frames than this share hold their CRC
FLAGGED_SHARE = 0.15  # of the bytes of good frames: the character format is off
BAUDS = (1200, 2400, 4800, 9600, 14400, 19200, 38400, 57600, 115200, 230400)
MAX_DURATIONS = 4096


class LineGroup(Group):
    def __init__(self) -> None:
        self.stats: dict[str, dict] = {}

    def _s(self, link: Link) -> dict:
        s = self.stats.get(link.name)
        if s is None:
            s = self.stats[link.name] = {"framing": 0, "parity": 0, "good_framing": 0, "good_parity": 0,
                                         "even": 0, "odd": 0, "durations": [], "frames": [], "bad": []}
        return s

    def request(self, f, link: Link, unit, codes: frozenset, key) -> None:
        self.noise(f, link, codes)

    def response(self, f, link: Link, unit, codes: frozenset, req) -> None:
        self.noise(f, link, codes)

    def other(self, f, link: Link, unit, codes: frozenset) -> None:
        self.noise(f, link, codes)

    def noise(self, f, link: Link, codes: frozenset) -> None:
        """Every frame: the first MAX_DURATIONS spans of per-byte timed ones, and the UART flags."""
        if f.time_source == "byte":
            s = self.stats.get(link.name) or self._s(link)
            d = s["durations"]
            if len(d) < MAX_DURATIONS:
                d.append((f.t_ns, f.t_end_ns))
        if not f.crc_ok:
            s = self.stats.get(link.name) or self._s(link)
            if len(s["bad"]) < 8:
                s["bad"].append(f.index)
        if not codes or UART.isdisjoint(codes):
            return
        s = self._s(link)
        good = bool(f.crc_ok) or CRC_UNPROVEN.code in codes  # the CRC matches (a flagged byte leaves it unproven)
        if len(s["frames"]) < 8:
            s["frames"].append(f.index)
        for a in f.annotations:
            if a.code == UART_FRAMING.code:
                s["framing"] += 1
                if good:
                    s["good_framing"] += 1
                    s["even" if bin(f.raw[a.start]).count("1") % 2 == 0 else "odd"] += 1
            elif a.code == UART_PARITY.code:
                s["parity"] += 1
                s["good_parity"] += good

    def findings(self, d: Diagnosis) -> list[Finding]:
        out = []
        for link in d.links.values():
            f = self._judge(d, link)
            if f is not None:
                out.append(f)
        return out

    def _judge(self, d: Diagnosis, link: Link) -> Finding | None:
        if link.bytes < MIN_BYTES or link.line is None:
            return None
        s = self.stats.get(link.name) or self._s(link)
        line = link.line
        share = link.matched_bytes / link.bytes
        ev = {"bytes": link.bytes, "bytes_in_good_frames": link.matched_bytes, "good_share": round(share, 3),
              "framing_errors": s["framing"], "parity_errors": s["parity"], "read_at": line.label()}
        span = dict(link=link.name, t_start=d.seconds(link.first_ns), t_end=d.seconds(link.last_ns),
                    frames=s["frames"] or s["bad"])
        if share < GOOD_SHARE and link.good_frames < GOOD_FRAMES * link.frames:
            # (at the wrong settings hardly a frame holds; a line whose requests hold and answers break is a unit's
            # fault, not the capture's)
            baud = _baud_from_bursts(s["durations"])
            if baud:
                try_ = f"the bursts' timing points to {baud[0]} baud ({baud[1]}): try --baud {baud[0]}"
                ev["baud_from_bursts"] = baud[0]
            else:
                try_ = ("the capture's times (per read) cannot tell the line's baud: run `sniffer detect PORT` on "
                        "the line, or try the drives' settings")
            return Finding(
                "wrong_line_settings", ERROR, evidence=ev, **span,
                text=f"Only {share:.0%} of the bytes read at {line.label()} make frames whose CRC holds: the line "
                     f"runs at other settings, and what is shown as units and requests here is noise.",
                action=f"Capture again at the line's settings; {try_}.")
        good = max(link.matched_bytes, 1)
        if s["good_parity"] > 0.9 * good:
            other = {"E": "O", "O": "E"}.get(line.parity, "N")
            return Finding(
                "wrong_line_settings", ERROR, evidence=ev, **span,
                text=f"Nearly every byte read at {line.label()} fails its parity check though the frames' CRCs "
                     f"hold: the line uses the other parity.",
                action=f"Read the line with --parity {other}.")
        if s["good_parity"] > FLAGGED_SHARE * good:
            return Finding(
                "wrong_line_settings", ERROR, evidence=ev, **span,
                text=f"{s['good_parity'] / good:.0%} of the bytes of good frames fail the parity check of "
                     f"{line.label()}: the line has no parity bit (its stop bit is read as one).",
                action="Read the line with --parity N (and --stopbits 2 if the drives are set to 8N2).")
        if s["good_framing"] > FLAGGED_SHARE * good and not s["parity"]:
            even = s["even"] / max(s["even"] + s["odd"], 1)
            parity = "E" if even > 0.8 else "O" if even < 0.2 else None
            ev["flagged_bytes_with_even_ones"] = round(even, 3)
            how = f"--parity {parity}" if parity else "--parity E or O"
            return Finding(
                "wrong_line_settings", ERROR, evidence=ev, **span,
                text=f"{s['good_framing'] / good:.0%} of the bytes of good frames fail their stop bit at "
                     f"{line.label()}: the line sends a parity bit there"
                     + (f" ({'even' if parity == 'E' else 'odd'}: the failing bytes are those whose parity bit "
                        f"is 0)" if parity else "") + ".",
                action=f"Read the line with {how}.")
        return None


def _baud_from_bursts(spans: list[tuple[int, int]]) -> tuple[int, str] | None:
    """The line's baud from the per-byte times of what a UART at the wrong baud read, or None.

    For each candidate (a common baud, 10 or 11 bits a character) the pieces are joined into bursts
    where they are less than 2 of its characters apart (inside a frame a line leaves less than one),
    and scored by the share of bursts lasting 8 of its characters (the master's usual request) give
    or take 0.6; the best candidate with at least 40 bursts, if 30 % of them fit it (else it cannot tell)."""
    if len(spans) < 40:
        return None
    best = None
    for baud in BAUDS:
        for bits, fmt in ((11, "8E1, 8O1 or 8N2"), (10, "8N1")):
            c = bits * 1e9 / baud
            bursts = []
            start, end = spans[0]
            for t0, t1 in spans[1:]:
                if t0 - end < 2 * c:
                    end = max(end, t1)
                    continue
                bursts.append(end - start)
                start, end = t0, t1
            bursts.append(end - start)
            if len(bursts) < 40:
                continue  # too slow a candidate: everything joins into a few bursts, one may fit by chance
            fit = sum(1 for b in bursts if abs(b / c - 8) < 0.6) / len(bursts)
            if best is None or fit > best[0]:
                best = (fit, baud, fmt)
    if best is None or best[0] < 0.3:
        return None
    return best[1], best[2]
