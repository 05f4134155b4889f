"""What the TDS-V8 table cannot say: Cn/Sn may only be written in PRG mode.

The drive's mode is tracked per unit from what crosses the bus: 0020H bit 4
in read responses (1 = DRV, 0 = PRG, zh-2021 7(2)) and the mode bits a write
to 0000H carries (bit 8 -> DRV, bit 9 -> PRG, zh-2021 7(1); they clear
themselves).  Until one of them is seen the mode is unknown and no write is
judged.  The mode is carried over into the next part of a capture (decoders/carry.py).
"""

from __future__ import annotations

from pathlib import Path

from sniffer.codes import ERROR, Code, note
from sniffer.frame import RESPONSE

from decoders.table_decoder import TableDecoder
from ..model_info import ModeCommand, ModeRegister
from ..tables import load_map

MAP_PATH = Path(__file__).with_name("registers.toml")
# this model's own code, declared beside the rule that emits it (TdsV8Decoder.codes claims it)
PRG_ONLY = Code("tds.write.prg_only", ERROR, "Cn/Sn parameter written while the drive is in DRV mode")


def load():
    return TdsV8Decoder(load_map(MAP_PATH))


class TdsV8Decoder(TableDecoder):
    codes = TableDecoder.codes + (PRG_ONLY,)
    carried_extra = ("mode",)

    def __init__(self, regmap) -> None:
        super().__init__(regmap)
        m = regmap.model
        self.prg_ranges = list(m.prg_only_ranges)
        mr = m.mode_register or ModeRegister(0x0020, 4)
        self.mode_addr, self.mode_bit = mr.addr, mr.bit
        mc = m.mode_command or ModeCommand(0x0000, 8, 9)
        self.cmd_addr, self.drv_bit, self.prg_bit = mc.addr, mc.to_drv_bit, mc.to_prg_bit

    def decode(self, f, request, state) -> None:
        super().decode(f, request, state)
        for pt in f.points:
            a = pt["address"]
            if a == self.mode_addr and f.role == RESPONSE and f.function in (0x03, 0x04):
                state.remember("mode", "DRV" if (pt["raw"] >> self.mode_bit) & 1 else "PRG")
            elif a == self.cmd_addr and f.function in (0x06, 0x10) and f.crc_ok:
                if (pt["raw"] >> self.drv_bit) & 1:
                    state.remember("mode", "DRV")
                elif (pt["raw"] >> self.prg_bit) & 1:
                    state.remember("mode", "PRG")

    def check_request(self, f, state) -> None:
        super().check_request(f, state)
        if f.function not in (0x06, 0x10) or state.extra.get("mode") != "DRV":
            return
        for pt in f.points:
            a = pt["address"]
            if any(lo <= a <= hi for lo, hi in self.prg_ranges):
                f.annotations.append(note(PRG_ONLY, f"{pt.get('id') or hex(a)} written in DRV mode "
                                          "(switch to PRG first: 0000H bit 9)", *pt["span"]))
