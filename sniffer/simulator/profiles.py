"""Real drive models on the simulated bus: which register is what, as data.

A `ModelProfile` says only what a register map cannot: which register a PLC
program writes its command word and setpoint to, which block it polls, what
each monitor word measures, which status bit means what.  Everything the map
already says is read from it (decoders.tables.load_map), so the simulated
drive and the sniffer's decoder share one source: scales and units, the
TDS-V8 frequency as a fraction of Cn-02, the fault tables (an enum code or
bit words, as the fault register's row says), exception codes and names,
function codes, register limits, the DRV/PRG write rule, the EEPROM save
register.

`Model` binds a profile to its loaded map and converts between physical
values and register words both ways (the drive encodes what it measures, the
PLC encodes what it commands).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import decoders
from decoders.tables import Register, RegisterMap, load_map

_MAPS = Path(decoders.__file__).parent


@dataclass(frozen=True, eq=False)
class ModelProfile:
    """What a PLC program and a drive of one model agree on (addresses as the manual prints them).

    quantities: monitor register -> what the drive puts there: freq_cmd,
        out_hz, out_v, current, dc_bus, torque (% of rated), ao_freq (analog
        output following the output frequency), relays (bit 0 running, bit 1
        fault).  Values are coded with the register's own scale and unit.
    status_bits: flag -> bit of the status word.  Flags: run, reverse, ready,
        fault, zero_speed, at_speed, class_400v (the mode bit, if the model
        has one, comes from the map's [model] mode_register).
    trips: the faults the drive trips with, by the mnemonic the map prints
        (an enum text such as "OC", or "(OC)" at the end of a fault bit name).
    exceptions: situation -> exception code the drive answers; every code
        must be in the map's [exceptions].  Situations: function, address,
        value, quantity (more registers than the map's limit), frame (reply
        longer than max_frame_bytes), read_only, mode (PRG-only register in
        DRV mode), locked, busy, eeprom (save failed).
    """

    model: str  # --device model id = the map's [model] id
    map_path: Path
    command: int  # command word register
    frequency: int  # frequency setpoint register
    monitor: tuple[int, int]  # (first register, count) the PLC polls every cycle
    status: int
    fault: tuple[int, ...]  # fault register(s)
    command_bits: dict[str, int]  # run, reverse, reset
    status_bits: dict[str, int]
    quantities: dict[int, str]
    trips: tuple[str, ...]
    exceptions: dict[str, int]
    params: dict[str, int] = field(default_factory=dict)  # manual id -> raw value at power-up
    max_hz: float = 60.0  # unless the frequency row is scaled through a parameter (TDS-V8 Cn-02)
    supply_v: float = 230.0
    locked: tuple[tuple[int, int], ...] = ()  # ranges that refuse writes (exception "locked")
    busy_ms: float = 0.0  # after an EEPROM save the drive answers "busy" this long
    eeprom_fail_prob: float = 0.0


TDS_V8 = ModelProfile(
    model="tds-v8",
    map_path=_MAPS / "tds_v8" / "registers.toml",
    command=0x0000,  # zh-2021 7(1)
    frequency=0x0001,  # 30000 = 100 % of Cn-02
    monitor=(0x0020, 16),  # 0020H-002FH, both manuals; 16 = the manual's register limit
    status=0x0020,
    fault=(0x0021, 0x0022),  # fault bits low / high word
    command_bits={"run": 0, "reverse": 1, "reset": 3},
    status_bits={"run": 0, "zero_speed": 1, "reverse": 2, "ready": 3, "fault": 7},
    quantities={0x0024: "freq_cmd", 0x0025: "out_hz", 0x0026: "out_v", 0x0027: "current",
                0x0028: "dc_bus", 0x002D: "ao_freq", 0x002F: "relays"},
    trips=("OC", "OV", "OH", "OL1"),
    # 03H for a DRV-mode Cn write is our pick: the manuals do not say what the drive answers
    exceptions={"function": 0x01, "address": 0x02, "value": 0x03, "quantity": 0x03, "read_only": 0x02,
                "mode": 0x03, "busy": 0x21, "eeprom": 0x22},
    params={"Cn-02": 600},  # max output frequency 60.0 Hz
    supply_v=220.0,  # 220 V class (Cn-01 150-255 V)
    busy_ms=60.0,
    eeprom_fail_prob=0.3,
)

A510 = ModelProfile(
    model="a510",
    map_path=_MAPS / "teco_a510" / "registers.toml",
    command=0x2501,
    frequency=0x2502,  # 0.01 Hz (the drive is set to at most 300 Hz)
    monitor=(0x2520, 16),  # 2520H-252FH
    status=0x2520,
    fault=(0x2521,),  # error description: a code
    command_bits={"run": 0, "reverse": 1, "reset": 3},
    status_bits={"run": 0, "reverse": 1, "ready": 2, "fault": 3, "zero_speed": 5, "class_400v": 6,
                 "at_speed": 7},
    quantities={0x2523: "freq_cmd", 0x2524: "out_hz", 0x2526: "dc_bus", 0x2527: "current",
                0x2529: "relays", 0x252A: "ao_freq"},
    trips=("OC", "OV", "OH1", "OL1"),
    exceptions={"function": 0x01, "address": 0x02, "value": 0x03, "read_only": 0x02,
                "quantity": 0x04},  # 04: "Register number is over 32" (the A510's own meaning)
    max_hz=60.0,
    supply_v=400.0,
)

SPL = ModelProfile(
    model="spl",
    map_path=_MAPS / "synplus_spl" / "registers.toml",
    command=0x0101,  # inverter control 0100H-011FH
    frequency=0x0102,  # 0.01 Hz
    monitor=(0x0120, 16),  # supervision 0120H-012FH
    status=0x0120,
    fault=(0x0121,),  # error content: a code
    command_bits={"run": 0, "reverse": 1, "reset": 3},
    status_bits={"run": 0, "reverse": 1, "ready": 2, "fault": 3},
    quantities={0x0123: "freq_cmd", 0x0124: "out_hz", 0x0125: "out_v", 0x0126: "dc_bus",
                0x0127: "current", 0x0129: "torque"},
    trips=("OC-A", "OC-C", "OV", "OH", "OL1"),
    # the SPL answers 51H-55H instead of the standard codes (manual 4. Exception Code)
    exceptions={"function": 0x51, "address": 0x52, "frame": 0x53, "quantity": 0x53, "value": 0x54,
                "read_only": 0x55, "locked": 0x55},
    locked=((0x0200, 0x0231),),  # ladder pages refuse writes while the PLC runs (manual line 216)
    max_hz=60.0,
    supply_v=220.0,
)

PROFILES: dict[str, ModelProfile] = {p.model: p for p in (TDS_V8, A510, SPL)}


@dataclass(frozen=True, slots=True)
class Trip:
    """One fault the drive can trip with: the fault registers' words and the manual's text."""

    label: str
    words: dict[int, int]


class Model:
    """A profile bound to its register map."""

    def __init__(self, profile: ModelProfile) -> None:
        self.profile = p = profile
        self.map: RegisterMap = load_map(p.map_path)
        if self.map.model_id != p.model:
            raise ValueError(f"{p.map_path}: map id {self.map.model_id!r}, profile {p.model!r}")
        for what, code in p.exceptions.items():
            if code not in self.map.exceptions:
                raise ValueError(f"{p.model}: exception {code:02X}H ({what}) is not in the map")
        regs = self.map.registers
        for addr in (p.command, p.frequency, p.status, *p.fault, *p.quantities):
            if addr not in regs:
                raise ValueError(f"{p.model}: register {addr:04X}H is not in the map")
        self.params = {self.map.by_id[k].addr: v for k, v in p.params.items()}
        info = self.map.model
        self.functions = frozenset(info.function_codes if info.function_codes is not None else (0x03, 0x06, 0x10))
        self.max_regs: int | None = info.max_registers_per_request
        self.max_frame: int | None = info.max_frame_bytes
        self.prg_only = list(info.prg_only_ranges)
        self.mode_register = info.mode_register
        self.mode_command = info.mode_command
        self.eeprom_save = info.eeprom_save
        self.trips = self._resolve_trips()

    # ------------------------------------------------------------ values
    def ref_value(self, r: Register, words: dict[int, int]) -> float | None:
        """The physical value of the register a row is scaled through (Cn-02), if any."""
        sb = r.scale_by
        if not sb:
            return None
        ref = self.map.registers[sb["addr"]]
        return words.get(ref.addr, self.params.get(ref.addr, ref.default or 0)) * ref.scale

    def encode(self, addr: int, value: float, words: dict[int, int]) -> int:
        """Physical value -> register word, with the row's scale (or its scale_by reference)."""
        r = self.map.registers[addr]
        ref = self.ref_value(r, words)
        raw = value / ref * r.scale_by["full"] if ref else value / r.scale
        return max(-0x8000 if r.type == "s16" else 0, min(0xFFFF, round(raw))) & 0xFFFF

    def decode(self, addr: int, raw: int, words: dict[int, int]) -> float:
        r = self.map.registers[addr]
        ref = self.ref_value(r, words)
        return raw * ref / r.scale_by["full"] if ref else raw * r.scale

    def max_hz(self, words: dict[int, int]) -> float:
        ref = self.ref_value(self.map.registers[self.profile.frequency], words)
        return ref if ref else self.profile.max_hz

    # ------------------------------------------------------------ faults
    def _resolve_trips(self) -> list[Trip]:
        out = []
        for mnemonic in self.profile.trips:
            trip = self._find_trip(mnemonic)
            if trip is None:
                raise ValueError(f"{self.profile.model}: fault {mnemonic!r} is not in the map's fault tables")
            out.append(trip)
        return out

    def _find_trip(self, mnemonic: str) -> Trip | None:
        for addr in self.profile.fault:
            r = self.map.registers[addr]
            if r.enum:
                for code, e in self.map.enums[r.enum].items():
                    if e.get("text") == mnemonic:
                        return Trip(self.map.enum_text(r.enum, code), {addr: code})
            elif r.bits:
                for b in self.map.bits[r.bits]:
                    if b["lo"] == b["hi"] and b.get("mnemonic") == mnemonic:
                        return Trip(b["name"], {addr: 1 << b["lo"]})
        return None


@cache
def get_model(model_id: str) -> Model:
    try:
        return Model(PROFILES[model_id])
    except KeyError:
        raise ValueError(f"no simulated drive for model {model_id!r}; known: {', '.join(PROFILES)}") from None
