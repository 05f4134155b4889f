"""Guess a unit's drive model from what it is polled for and how it answers.

Evidence per frame (CRC-good requests and exception responses):
  * a request whose whole register range exists (not reserved) in exactly one
    model's map is strong evidence for that model; in several maps, weak
    evidence for each;
  * an exception code only one model defines is strong evidence for it.
A guess is made once a model has at least MIN_STRONG strong hits and at
least 90 % of the unit's evidence, and no other model has strong hits.  A
user's device map always wins; if the traffic clearly points elsewhere the
registry annotates the contradiction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sniffer.frame import REQUEST, Frame

MIN_STRONG = 3
SETTLED = 200  # evidence frames after which a unit's verdict stands (keeps the hot path cheap)


@dataclass
class UnitEvidence:
    strong: dict[str, int] = field(default_factory=dict)
    weak: dict[str, int] = field(default_factory=dict)
    seen: int = 0
    examples: dict[str, list[str]] = field(default_factory=dict)
    guess: str | None = None
    confidence: float = 0.0


class Identifier:
    def __init__(self, maps: dict) -> None:
        """maps: {model id: RegisterMap} of the candidate models (variants sharing a map count once)."""
        self.maps = maps
        self.units: dict[int, UnitEvidence] = {}
        self._cover_cache: dict[tuple[int, int], list[str]] = {}  # polls repeat: remember each range

    def _covering(self, a: int, q: int) -> list[str]:
        key = (a, q)
        hit = self._cover_cache.get(key)
        if hit is not None:
            return hit
        if len(self._cover_cache) > 65536:
            self._cover_cache.clear()
        out = self._cover_cache[key] = []
        for mid, m in self.maps.items():
            regs = m.registers
            ok = True
            for addr in range(a, a + q):
                r = regs.get(addr)
                if r is None or r.access == "reserved":
                    ok = False
                    break
            if ok:
                out.append(mid)
        return out

    def settled(self, unit: int) -> bool:
        """True once a unit's verdict stands: observe() will not change it any more."""
        ev = self.units.get(unit)
        return ev is not None and ev.seen >= SETTLED

    def observe(self, f: Frame) -> tuple[str, float, str] | None:
        """Feed one decoded-or-not frame; returns (model, confidence, evidence) when the guess changes."""
        if not f.crc_ok or f.unit in (None, 0) or len(f.adu) < 3:
            return None
        ev = self.units.get(f.unit)
        if ev is not None and ev.seen >= SETTLED:
            return None
        fc = f.function
        models: list[str] = []
        label = ""
        if f.role == REQUEST and fc in (0x03, 0x04, 0x06, 0x10) and len(f.adu) >= 6:
            a = (f.adu[2] << 8) | f.adu[3]
            q = 1 if fc == 0x06 else ((f.adu[4] << 8) | f.adu[5])
            if not 1 <= q <= 125:
                return None
            models = self._covering(a, q)
            label = f"{a:04X}H" + (f"-{a + q - 1:04X}H" if q > 1 else "")
        elif fc & 0x80:
            code = f.adu[2]
            if code > 0x0B:
                models = [mid for mid, m in self.maps.items() if code in m.exceptions]
                label = f"exception {code:02X}H"
        else:
            return None
        if ev is None:
            ev = self.units[f.unit] = UnitEvidence()
        ev.seen += 1
        if len(models) == 1:
            ev.strong[models[0]] = ev.strong.get(models[0], 0) + 1
            ex = ev.examples.setdefault(models[0], [])
            if label not in ex and len(ex) < 4:
                ex.append(label)
        for mid in models:
            ev.weak[mid] = ev.weak.get(mid, 0) + 1
        return self._decide(ev)

    def _decide(self, ev: UnitEvidence):
        if not ev.strong:
            return None
        best = max(ev.strong, key=lambda m: (ev.strong[m], m))
        others = sum(n for m, n in ev.strong.items() if m != best)
        hits = ev.weak.get(best, 0)
        conf = hits / ev.seen
        if ev.strong[best] < MIN_STRONG or others or conf < 0.9:
            return None
        changed = best != ev.guess
        ev.guess, ev.confidence = best, conf
        if not changed:
            return None
        evidence = (f"{hits} of {ev.seen} requests fit the {best} map; {ev.strong[best]} only {best} has "
                    f"({', '.join(ev.examples.get(best, []))})")
        return best, conf, evidence
