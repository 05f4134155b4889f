"""The kinds of finding `sniffer diagnose` gives: one table, read by the engine, the text and JSON, the report,
the TUI and the docs (tests/test_diagnose.py checks that docs/diagnose.md names every one).

Each kind says what it means on the line, how bad it is when found (a finding may be milder when its
evidence is), and the group module that decides it.
"""

from __future__ import annotations

from dataclasses import dataclass

from sniffer.codes import ERROR, INFO, WARNING


@dataclass(frozen=True)
class Kind:
    name: str
    severity: str  # when found with its full evidence
    means: str
    group: str  # the module of sniffer/diagnose that decides it


KINDS: tuple[Kind, ...] = (
    Kind("wrong_line_settings", ERROR, "the capture's baud, parity or stop bits are not the line's", "line"),
    Kind("second_master", ERROR, "another master on the same bus", "masters"),
    Kind("driver_enable_late", ERROR, "a slave's transmitter turns on after its first start bit", "wiring"),
    Kind("driver_disable_early", ERROR, "a slave's transmitter turns off before its last stop bit", "wiring"),
    Kind("unit_silent", ERROR, "a polled unit never answers, or stops answering for a while", "units"),
    Kind("drive_fault", ERROR, "a drive trips", "drives"),
    Kind("eeprom_wear", ERROR, "the save command is written far too often for the EEPROM's endurance", "params"),
    Kind("timeout_too_short", WARNING, "a unit answers after the master has given up", "timing"),
    Kind("bus_unbiased", WARNING, "no fail-safe bias (or a termination problem): the idle line floats", "wiring"),
    Kind("noise_correlated_with_load", WARNING, "interference that tracks what a drive does (motor cable, PWM)",
         "correlate"),
    Kind("params_not_saved", WARNING, "parameters written but never saved to non-volatile memory", "params"),
    Kind("params_changed", WARNING, "a drive's parameters differ from the reference set (--params)", "params"),
    Kind("retry_storm", WARNING, "the master spends a large share of the line on retries", "masters"),
    Kind("latency_drift", WARNING, "a unit's response time grows (or shrinks) through the capture", "timing"),
    Kind("unit_refuses", WARNING, "the master keeps asking a unit for something it refuses (exceptions)", "units"),
    Kind("answers_broadcast", WARNING, "a unit answers broadcasts (unit 0), which no unit may", "units"),
    Kind("line_damage", WARNING, "frames damaged on the line and no cause told from the bytes", "damage"),
    Kind("poll_redundant", INFO, "registers polled far more often than they change", "polls"),
    Kind("poll_cycle", INFO, "the poll cycle, how busy the line is, and the room left at this baud", "polls"),
)
BY_NAME: dict[str, Kind] = {k.name: k for k in KINDS}
ORDER: dict[str, int] = {k.name: i for i, k in enumerate(KINDS)}
SEVERITY_RANK = {ERROR: 0, WARNING: 1, INFO: 2}
