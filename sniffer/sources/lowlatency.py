"""Ask the adapter to hand bytes to us sooner, and record whether it listened.

A per-read timestamp is only as good as the delay between a byte crossing
the wire and `read()` returning it.  Two Linux knobs shrink that delay:

* ASYNC_LOW_LATENCY (TIOCGSERIAL/TIOCSSERIAL, the `setserial low_latency`
  flag): UART drivers push received bytes to the tty layer at once instead
  of from a deferred work item.  Only drivers with a serial_struct answer;
  a pty or a CDC-ACM modem says ENOTTY/EINVAL.
* The FTDI latency timer (sysfs `latency_timer`, ms): an FT232 holds bytes
  up to 16 ms by default before sending a USB packet, which smears
  inter-frame gaps far beyond t3.5.  Writing 1 needs root or a udev rule.

Neither knob touches the serial line: they configure the driver or the USB
chip, no byte is transmitted.  The outcome goes into the capture metadata
so a reader of the capture knows how far host times can be trusted.
"""

from __future__ import annotations

import errno
import fcntl
import os
import struct
import termios

ASYNC_LOW_LATENCY = 1 << 13
# struct serial_struct (linux/serial.h): int type, line; unsigned port; int irq, flags; ...
_FLAGS_OFFSET = 16
_SERIAL_STRUCT_SIZE = 128  # 72 on x86_64; room to spare, the kernel copies only its size
LATENCY_TIMER_WANTED_MS = 1


def request_low_latency(fd: int, port: str, sysfs: str = "/sys") -> dict:
    """Try both knobs on an open tty; return what was requested and what took effect.

    Shape (JSON-friendly, goes to CaptureInfo.low_latency):

        {"requested": True,
         "took_effect": bool,             # at least one knob is now on
         "async_low_latency": bool,       # flag read back as set
         "reason": str,                   # only when async_low_latency is False
         "latency_timer": {"requested": 1, "before": int|None, "after": int|None,
                           "took_effect": bool, "path": str, "reason": str (on failure)},
         "adapter": {...}}                # USB ids from pyserial, real /sys only
    """
    out: dict = {"requested": True}
    ok, reason = _async_low_latency(fd)
    out["async_low_latency"] = ok
    if not ok:
        out["reason"] = reason
    out["latency_timer"] = _latency_timer(port, sysfs)
    out["took_effect"] = ok or out["latency_timer"]["took_effect"]
    if sysfs == "/sys":
        adapter = _adapter(port)
        if adapter:
            out["adapter"] = adapter
    return out


def _async_low_latency(fd: int) -> tuple[bool, str]:
    buf = bytearray(_SERIAL_STRUCT_SIZE)
    try:
        fcntl.ioctl(fd, termios.TIOCGSERIAL, buf, True)
    except OSError as e:
        why = "no UART driver behind this port, e.g. a pty" if e.errno in (errno.ENOTTY, errno.EINVAL) else ""
        return False, _explain("TIOCGSERIAL", e, why)
    (flags,) = struct.unpack_from("i", buf, _FLAGS_OFFSET)
    if flags & ASYNC_LOW_LATENCY:
        return True, ""
    struct.pack_into("i", buf, _FLAGS_OFFSET, flags | ASYNC_LOW_LATENCY)
    try:
        fcntl.ioctl(fd, termios.TIOCSSERIAL, bytes(buf))
        back = bytearray(_SERIAL_STRUCT_SIZE)
        fcntl.ioctl(fd, termios.TIOCGSERIAL, back, True)
    except OSError as e:
        return False, _explain("TIOCSSERIAL", e, "")
    if struct.unpack_from("i", back, _FLAGS_OFFSET)[0] & ASYNC_LOW_LATENCY:
        return True, ""
    return False, "driver accepted ASYNC_LOW_LATENCY but does not keep it"


def _latency_timer(port: str, sysfs: str) -> dict:
    name = os.path.basename(os.path.realpath(port))  # /dev/serial/by-id/... -> ttyUSB0
    path = os.path.join(sysfs, "bus", "usb-serial", "devices", name, "latency_timer")
    rec: dict = {"requested": LATENCY_TIMER_WANTED_MS, "before": None, "after": None,
                 "took_effect": False, "path": path}
    if not os.path.exists(path):
        rec["reason"] = f"no latency_timer for {os.path.realpath(port)} (not an FTDI adapter)"
        return rec
    try:
        rec["before"] = _read_int(path)
        if rec["before"] != LATENCY_TIMER_WANTED_MS:
            with open(path, "w") as fh:
                fh.write(f"{LATENCY_TIMER_WANTED_MS}\n")
        rec["after"] = _read_int(path)
    except (OSError, ValueError) as e:
        hint = "needs root or a udev rule" if getattr(e, "errno", None) in (errno.EACCES, errno.EPERM) else ""
        rec["reason"] = _explain("latency_timer", e, hint)
        return rec
    rec["took_effect"] = rec["after"] == LATENCY_TIMER_WANTED_MS
    if not rec["took_effect"]:
        rec["reason"] = f"wrote {LATENCY_TIMER_WANTED_MS}, read back {rec['after']}"
    return rec


def _adapter(port: str) -> dict:
    """USB identity of the adapter (pyserial's sysfs walk): explains the timing quality."""
    try:
        from serial.tools.list_ports_linux import SysFS

        info = SysFS(os.path.realpath(port))
    except Exception:  # best effort: metadata only, never a reason to fail a capture
        return {}
    if info.vid is None:
        return {}
    return {"vid": f"{info.vid:04x}", "pid": f"{info.pid:04x}", "manufacturer": info.manufacturer,
            "product": info.product, "serial_number": info.serial_number}


def _read_int(path: str) -> int:
    with open(path) as fh:
        return int(fh.read().strip())


def _explain(what: str, e: Exception, hint: str) -> str:
    text = f"{what}: {getattr(e, 'strerror', None) or e}"
    return f"{text} ({hint})" if hint else text
