"""`sniffer extcap --capture`: the values of Wireshark's dialog into the commands that capture (commands/extcap.py
runs them): a `sniffer live ... --format pcapng` whose stdout is Wireshark's fifo.

`detect` (the default of baud, parity and stop bits) on a serial port first runs `sniffer detect PORT
--write-bus` (listening only, its lines on stderr), then captures with that bus file; a value chosen in the
dialog wins over what was detected.  A bus file chosen in the dialog is taken as it is.  Wireshark stops
a capture with SIGTERM: `live` ends as on Ctrl-C, its last packets flushed.
"""

from __future__ import annotations

from sniffer.extcap.interfaces import Target

DETECT = "detect"
DETECT_MAX_S = "30"  # how long `detect` may listen before the capture gives up (Wireshark shows the error)


def live_argv(target: Target, baud: str, parity: str, stopbits: str, bus: str | None, rx: str | None) -> list[str]:
    """The `sniffer live` command line of a capture (with `bus`: the dialog's or the detected one)."""
    argv = ["live"]
    if target.kind == "bus":
        argv += ["--bus", target.what]
    elif target.kind == "link":  # one [[links]] table of the bus file, alone
        argv += ["--bus", target.what, f"--only-link={target.link}"]
    elif target.kind == "sigrok":
        argv += [f"sigrok:{target.what}", "--rx", rx or "D0"]
    else:
        argv.append(target.what)
    if bus and target.kind not in ("bus", "link"):
        argv += ["--bus", bus]
    for flag, value in (("--baud", baud), ("--parity", parity), ("--stopbits", stopbits)):
        if value and value != DETECT:
            argv += [flag, value]
    return argv + ["--headless", "--format", "pcapng", "--no-out"]


def detect_argv(target: Target, baud: str, parity: str, stopbits: str, bus: str | None, out: str) -> list[str] | None:
    """The `sniffer detect` command line to run first (writing bus file `out`), or None: a serial port whose
    settings the dialog does not give (nor a bus file) is listened to first."""
    if target.kind != "port" or bus or DETECT not in (baud, parity, stopbits):
        return None
    argv = ["detect", target.what, "--write-bus", out, "--max-time", DETECT_MAX_S]
    return argv + (["--bauds", baud] if baud != DETECT else [])
