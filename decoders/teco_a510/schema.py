"""What the A510 table cannot say: frequency resolution depends on a setting.

Manual l.281 (footnote to 2502H) and l.409: "If the maximum output frequency
of the motor is over 300Hz, the frequency resolution is 0.1Hz"; otherwise
0.01 Hz.  The condition is the drive's maximum-frequency *setting*, which
the manual does not tie to a register, so a passive sniffer cannot see it:

* model `a510` assumes 0.01 Hz and says so on every frame with a frequency;
  a raw value above 30000 (300.00 Hz) cannot be 0.01 Hz, so from then on
  the unit is taken as a high-frequency drive (0.1 Hz) and that is flagged;
* model `a510-hf` is for drives configured above 300 Hz: always 0.1 Hz.
"""

from __future__ import annotations

from pathlib import Path

from sniffer.codes import A510_ASSUMED as ASSUMED
from sniffer.codes import A510_SWITCHED as SWITCHED
from sniffer.codes import note

from ..model import TableDecoder
from ..tables import Register, load_map

RULE = "a510_fmax_over_300hz"
MAP_PATH = Path(__file__).with_name("registers.toml")


def load() -> "A510Decoder":
    return A510Decoder(load_map(MAP_PATH))


def load_high_frequency() -> "A510Decoder":
    return A510Decoder(load_map(MAP_PATH), high_frequency=True)


class A510Decoder(TableDecoder):
    extra_codes = (ASSUMED, SWITCHED)

    def __init__(self, regmap, high_frequency: bool = False) -> None:
        super().__init__(regmap)
        self.high_frequency = high_frequency
        if high_frequency:
            self.model = regmap.model_id + "-hf"

    @property
    def map_note(self) -> str:
        """What the table does not say for this model (decoders.mapfile writes it above the map)."""
        if self.high_frequency:
            return f"Model {self.model}: rows with scale_rule = \"{RULE}\" are 0.1 Hz per count, not their scale."
        return (f"Rows with scale_rule = \"{RULE}\" are 0.01 Hz per count (their scale) until a raw value above "
                "30000 shows the drive runs at 0.1 Hz per count.")

    def value_of(self, r: Register, raw: int, state):
        if r.scale_rule != RULE:
            return super().value_of(r, raw, state)
        if not self.high_frequency and raw > 30000 and not state.extra.get("a510_hf"):
            state.extra["a510_hf"] = "switched"
        hf = self.high_frequency or bool(state.extra.get("a510_hf"))
        return (round(raw * 0.1, 1) if hf else round(raw * 0.01, 2)), "Hz", False

    def decode(self, f, request, state) -> None:
        was = state.extra.get("a510_hf")
        super().decode(f, request, state)
        freq = [p for p in f.points if (r := self.map.registers.get(p["address"])) and r.scale_rule == RULE]
        if not freq or self.high_frequency:
            return
        if state.extra.get("a510_hf") == "switched" and not was:
            f.annotations.append(note(SWITCHED, f"{freq[0]['name']} raw {freq[0]['raw']}", 0, len(f.raw)))
            state.extra["a510_hf"] = "known"
        elif not state.extra.get("a510_hf"):
            f.annotations.append(note(ASSUMED, "0.01 Hz per count assumed (model a510-hf: 0.1 Hz)", 0, len(f.raw)))
