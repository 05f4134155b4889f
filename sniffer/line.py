"""Serial line settings and the Modbus serial-line timings derived from them."""

from __future__ import annotations

from dataclasses import dataclass

PARITIES = ("N", "E", "O")


class SettingsError(ValueError):
    """A serial setting that cannot be right (one clear line for the user)."""


@dataclass(slots=True, frozen=True)
class LineSettings:
    baud: int = 9600
    parity: str = "N"
    stopbits: int = 1
    databits: int = 8

    def __post_init__(self) -> None:
        if not isinstance(self.baud, int) or self.baud < 50 or self.baud > 4_000_000:
            raise SettingsError(f"baud rate {self.baud!r} is out of range (50..4000000)")
        if self.parity not in PARITIES:
            raise SettingsError(f"parity {self.parity!r} must be one of N, E, O")
        if self.stopbits not in (1, 2):
            raise SettingsError(f"stop bits {self.stopbits!r} must be 1 or 2")
        if self.databits not in (7, 8):
            raise SettingsError(f"data bits {self.databits!r} must be 7 or 8")

    @property
    def bits_per_char(self) -> int:
        """Start + data + parity + stop bits: 11 for 8E1/8O1/8N2, 10 for 8N1."""
        return 1 + self.databits + (0 if self.parity == "N" else 1) + self.stopbits

    @property
    def char_ns(self) -> int:
        return self.bits_per_char * 1_000_000_000 // self.baud

    @property
    def t15_ns(self) -> int:
        """Inter-character timeout; fixed 750 us above 19200 baud (Modbus serial line spec 2.5.1.1)."""
        if self.baud > 19200:
            return 750_000
        return self.char_ns * 3 // 2

    @property
    def t35_ns(self) -> int:
        """Inter-frame delay; fixed 1.75 ms above 19200 baud."""
        if self.baud > 19200:
            return 1_750_000
        return self.char_ns * 7 // 2

    def label(self) -> str:
        return f"{self.baud} {self.databits}{self.parity}{self.stopbits}"
