"""What the A510 table cannot say: frequency resolution depends on a setting.

Manual l.281 (footnote to 2502H) and l.409: "If the maximum output frequency
of the motor is over 300Hz, the frequency resolution is 0.1Hz"; otherwise
0.01 Hz.  The condition is the drive's maximum-frequency *setting*, which
the manual does not tie to a register, so a passive sniffer cannot see it:

* model `a510` is a drive set to at most 300 Hz: 0.01 Hz per count, and says so
  on every frame with a frequency (an info note);
* model `a510-hf` is for drives configured above 300 Hz: always 0.1 Hz.

A confirmed raw value above 30000 (a read answer's, or a write the drive
acknowledged: what the drive holds, not what a PLC asked) cannot be 0.01 Hz, so
the unit is then an `a510-hf`: from that frame on its frames are decoded as model
`a510-hf` (the frame's `model` says so, and a view keeps its values apart from
the ones decoded before), flagged once, and carried over into the next part of
the capture (decoders/carry.py).  The bus file states it with `[units] N = "a510-hf"`.
"""

from __future__ import annotations

from pathlib import Path

from sniffer.codes import INFO, WARNING, Code, note
from sniffer.frame import RESPONSE

from decoders.table_decoder import TableDecoder
from ..tables import Register, load_map

RULE = "a510_fmax_over_300hz"
MAP_PATH = Path(__file__).with_name("registers.toml")
# this model's own codes, declared beside the rule that emits them (A510Decoder.codes claims them)
ASSUMED = Code(
    "a510.freq.resolution", INFO,
    "frequency resolution assumed (0.1 Hz if the drive's maximum frequency is over 300 Hz)",
)
SWITCHED = Code(
    "a510.freq.high", WARNING,
    "a frequency above 300.00 Hz: the drive must be set above 300 Hz, so 0.1 Hz resolution applies",
)


def load() -> "A510Decoder":
    return A510Decoder(load_map(MAP_PATH))


def load_high_frequency() -> "A510Decoder":
    return A510Decoder(load_map(MAP_PATH), high_frequency=True)


class A510Decoder(TableDecoder):
    codes = TableDecoder.codes + (ASSUMED, SWITCHED)
    carried_extra = ("a510_hf",)

    def __init__(self, regmap, high_frequency: bool = False) -> None:
        super().__init__(regmap)
        self.high_frequency = high_frequency
        self.base_model = regmap.model_id
        if high_frequency:
            self.model = regmap.model_id + "-hf"
        self.freq_addrs = frozenset(a for a, r in regmap.registers.items() if r.scale_rule == RULE)

    @property
    def map_note(self) -> str:
        """What the table does not say for this model (decoders.mapfile writes it above the map)."""
        if self.high_frequency:
            return f"Model {self.model}: rows with scale_rule = \"{RULE}\" are 0.1 Hz per count, not their scale."
        return (f"Rows with scale_rule = \"{RULE}\" are 0.01 Hz per count (their scale); a unit that shows a "
                f"confirmed raw value above 30000 is decoded as {self.base_model}-hf (0.1 Hz per count) from then on.")

    def value_of(self, r: Register, raw: int, state):
        if r.scale_rule != RULE:
            return super().value_of(r, raw, state)
        hf = self.high_frequency or bool(state.extra.get("a510_hf"))
        return (round(raw * 0.1, 1) if hf else round(raw * 0.01, 2)), "Hz", False

    def decode(self, f, request, state) -> None:
        switched = None
        if not self.high_frequency and not state.extra.get("a510_hf"):
            switched = self._confirmed_high(f, request)
            if switched is not None:
                state.remember("a510_hf", True)
        super().decode(f, request, state)
        if self.high_frequency:
            return
        if state.extra.get("a510_hf"):
            f.model = self.base_model + "-hf"  # what the frame was decoded as (0.1 Hz per count)
            if switched is not None:
                r = self.map.registers[switched[0]]
                f.annotations.append(note(SWITCHED, f"{r.name} ({switched[0]:04X}H) raw {switched[1]}: decoded as "
                                                    f"{f.model} from here on", 0, len(f.raw)))
        elif any(p.get("address") in self.freq_addrs for p in f.points):
            f.annotations.append(note(ASSUMED, "0.01 Hz per count assumed (model a510-hf: 0.1 Hz)", 0, len(f.raw)))

    def _confirmed_high(self, f, request) -> tuple[int, int] | None:
        """(address, raw) of a frequency above 30000 counts that this frame confirms the drive holds: a read
        answer's value, a single write's echo, or the values of a write request this answer acknowledges."""
        if f.role != RESPONSE or not f.crc_ok or f.function not in (0x03, 0x06, 0x10):
            return None
        adu, fc = f.adu, f.function
        if fc == 0x06:
            if len(adu) < 6:
                return None
            start, data = (adu[2] << 8) | adu[3], adu[4:6]
        elif request is None or not request.crc_ok or len(request.adu) < 6 or request.function != fc:
            return None
        elif fc == 0x03:
            start, data = (request.adu[2] << 8) | request.adu[3], adu[3:3 + (adu[2] if len(adu) > 2 else 0)]
        else:
            if request.adu[2:6] != adu[2:6]:
                return None
            start, data = (request.adu[2] << 8) | request.adu[3], request.adu[7:]
        for a in self.freq_addrs:
            k = 2 * (a - start)
            if 0 <= k and k + 2 <= len(data):
                raw = (data[k] << 8) | data[k + 1]
                if raw > 30000:
                    return a, raw
        return None
