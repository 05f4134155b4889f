"""A logic analyzer's capture, decoded by sigrok-cli's UART decoder: a .sr file or a live analyzer.

    src = file_source("line.sr", logic)             # sigrok-cli -i line.sr ...
    src = device_source(DeviceSpec.parse("sigrok:fx2lafw"), logic)
                                                    # sigrok-cli -d fx2lafw -c samplerate=1M --continuous ...
    info = src.open()      # sigrok-cli started; CaptureError (one line): no sigrok-cli, no such channel/driver
    for ev in src.events(): ...                     # per-byte Chunks and Ticks, read as sigrok-cli prints them

One code path for both: only the acquisition options differ (`-i FILE` or
`-d DRIVER ... --continuous`; `live=True` also gives sigrok-cli a stdin pipe,
its "press any key" to stop).  sigrok-cli runs as a subprocess at log level 4;
its stdout (the annotations, sources/sigrok_uart.py) is read as it comes, never
whole; its stderr says when the decoders have read a block of samples ("Done,
handled all samples": a watermark, applied once stdout is drained, up to which
the annotations are read: SigrokUart.watermark), and gives the error line when
sigrok-cli fails.  Nothing is sent to any device: the
only options are the sample rate and the channels to read.

The capture's metadata (CaptureInfo.extra): `samplerate` (Hz), `logic` (the
channels), `channel_roles` (wire -> request/response, sniffer.capture.pipeline.roles_of)
and `sigrok` (the input or the device).  Byte times are ns from sample 0.
"""

from __future__ import annotations

import os
import re
import select
import shutil
import subprocess
import threading
import time
from collections import deque
from collections.abc import Iterator

from sniffer.events import CaptureInfo
from sniffer.events import CaptureError
from sniffer.orphans import external_ends_with_parent
from sniffer.sources.logic_options import DeviceSpec, LogicSpec
from sniffer.sources.sigrok_uart import UART, SigrokUart, decoder_args

DEFAULT_RATE = 1_000_000
MIN_SAMPLES_PER_BIT = 4
START_TIMEOUT_S = 20.0  # sigrok-cli must start decoding (or fail) within this
STOP_GRACE_S = 5.0  # after "any key": then it is terminated
_RATE_LINE = re.compile(rb"srd: Setting session \d+ samplerate to (\d+)")
_DECODING = re.compile(rb"srd: Decoding: abs start sample \d+, abs end sample \d+ .*instance ([\w-]+)")
_DONE = re.compile(rb"srd: Done, handled all samples \(abs cur (\d+)")
_ERROR = re.compile(rb"error|fail|not found|no device|critical|cannot|can't|couldn't|unable|unknown", re.I)
_CHANNELS = re.compile(r" with \d+ channels?: (.*)$")
# libsigrokdecode 0.5.3 (Debian 12) drops references to Python's True/False it does not own (fixed upstream in
# 2021): with some decoder setups the interpreter aborts while shutting down, after every annotation is out
FINALIZE_CRASH = b"Python runtime state: finalizing"


def sigrok_cli() -> str:
    """sigrok-cli's path; CaptureError when it is not installed."""
    path = shutil.which("sigrok-cli")
    if path is None:
        raise CaptureError("sigrok-cli not found: a logic capture is decoded by sigrok's UART decoder; install it "
                           "(Debian/Ubuntu: apt-get install sigrok-cli; scripts/install-system-deps.sh)")
    return path


def _check_channels(where: str, logic: LogicSpec, channels) -> None:
    for flag, name in (("--rx", logic.rx), ("--tx", logic.tx), ("--de", logic.de)):
        if name is not None and name not in channels:
            raise CaptureError(f"{where}: no logic channel {name!r} for {flag} (channels: {', '.join(channels)})")


def file_source(path: str, logic: LogicSpec | None, damage: list[str] | None = None) -> SigrokSource:
    """The source of a .sr file (its channels and sample rate from its metadata)."""
    from sniffer.sources.srzip import logic_blocks, read_meta

    meta = read_meta(path)
    if logic is None:
        raise CaptureError(f"{path}: a sigrok logic capture: say which channel carries the line, --rx CHANNEL "
                           f"(channels: {', '.join(meta.channels)}), and its --baud")
    _check_channels(path, logic, meta.channels)
    de0 = 0
    if logic.de is not None:
        first = next(logic_blocks(meta, 64 * meta.unitsize), b"")
        de0 = (int.from_bytes(first[:meta.unitsize], "little") >> meta.channels[logic.de]) & 1
    src = SigrokSource(logic, path, ["-i", path], meta.samplerate, list(meta.channels), damage=damage, de_initial=de0)
    src.total_samples = meta.samples
    return src


def device_channels(device: DeviceSpec) -> list[str]:
    """The analyzer's logic channels (`sigrok-cli -d ... --show`); CaptureError: unknown driver, no device."""
    try:
        p = subprocess.run([sigrok_cli(), "-d", device.arg, "--show"], stdin=subprocess.DEVNULL,
                           capture_output=True, timeout=START_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise CaptureError(f"{device}: sigrok-cli found no answer from the analyzer in {START_TIMEOUT_S:.0f} s") \
            from None
    text = p.stdout.decode("utf-8", "replace") + "\n" + p.stderr.decode("utf-8", "replace")
    for line in text.splitlines():
        m = _CHANNELS.search(line)
        if m and line.startswith(device.driver):
            names = m.group(1).split()
            return [n for n in names if not re.fullmatch(r"A\d+", n)] or names  # logic ones (analog: A0 ...)
    why = next((x.strip() for x in text.splitlines() if _ERROR.search(x.encode())), "") or "no device found"
    raise CaptureError(f"{device}: {why} (sigrok-cli -d {device.arg} --show; `sigrok-cli --scan` lists analyzers)")


def device_source(device: DeviceSpec, logic: LogicSpec) -> SigrokSource:
    """The source of a live analyzer: its channels checked, read continuously at --samplerate (default 1 MHz)."""
    channels = device_channels(device)
    _check_channels(str(device), logic, channels)
    rate = logic.samplerate or DEFAULT_RATE
    from sniffer.sources.srzip import rate_text

    acquire = ["-d", device.arg, "-c", f"samplerate={rate}", "--continuous", "-C", ",".join(logic.channels)]
    src = SigrokSource(logic, str(device), acquire, rate, channels, live=True)
    src.rate_label = rate_text(rate)
    return src


class SigrokSource:
    """sigrok-cli's UART decode of a capture as a stream of events (see the module doc)."""

    def __init__(self, logic: LogicSpec, where: str, acquire: list[str], samplerate: int, channels: list[str], *,
                 live: bool = False, damage: list[str] | None = None, de_initial: int = 0) -> None:
        self.logic = logic
        self.where = where
        self.acquire = list(acquire)
        self.samplerate = samplerate
        self.channels = channels
        self.live = live
        self.damage: list[str] = [] if damage is None else damage
        self.de_initial = de_initial
        self.total_samples: int | None = None
        self.rate_label = ""
        self.proc: subprocess.Popen | None = None
        self.info: CaptureInfo | None = None
        self.uart: SigrokUart | None = None
        self.watermark = 0
        self.errors: deque[str] = deque(maxlen=5)
        self._stop = threading.Event()
        self._closed = False
        self._err_buf = b""
        self._last_instance = b""
        self._pending_wm: list[int] = []  # the UART's "done up to" samples read from stderr, not yet applied
        self._started_decoding = False
        self.finalize_crash = False

    @property
    def argv(self) -> list[str]:
        return ["-l", "4", *self.acquire, *decoder_args(self.logic, self.logic.line(self.where))]

    def open(self) -> CaptureInfo:
        if self.info is not None:
            return self.info
        line = self.logic.line(self.where)
        if self.samplerate < MIN_SAMPLES_PER_BIT * line.baud:
            raise CaptureError(f"{self.where}: {self.samplerate:,} samples/s is too slow for {line.baud} baud "
                               f"(at least {MIN_SAMPLES_PER_BIT} samples a bit: --samplerate "
                               f"{MIN_SAMPLES_PER_BIT * line.baud:,} or more)")
        exe = sigrok_cli()
        self.uart = SigrokUart(self.logic, line, self.samplerate, self.de_initial)
        wall = time.time_ns()
        # a session of its own: the terminal's Ctrl-C reaches the capture, which stops sigrok-cli with its key (a
        # sigrok-cli killed by the signal would end without what it had decoded)
        self.proc = subprocess.Popen([exe, *self.argv], stdin=subprocess.PIPE if self.live else subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                                     preexec_fn=external_ends_with_parent())
        for fd in (self.proc.stdout.fileno(), self.proc.stderr.fileno()):
            os.set_blocking(fd, False)
        try:
            self._await_start()
        except BaseException:
            self.close()
            raise
        info = CaptureInfo(source=f"sigrok:{self.where}", port=self.where if self.live else "", baud=line.baud,
                           parity=line.parity, stopbits=line.stopbits, databits=line.databits, time_source="byte",
                           t0_ns=0, wall_anchor_ns=wall if self.live else 0)
        info.extra["samplerate"] = self.samplerate
        info.extra["logic"] = self.logic.to_dict()
        info.extra["channels"] = [c for c in (self.logic.rx, self.logic.tx,
                                              self.logic.de_channel if self.logic.de else None) if c]
        roles = self.logic.roles()
        if roles:
            info.extra["channel_roles"] = roles
        info.extra["sigrok"] = {"device" if self.live else "input": self.where}
        self.info = info
        return info

    def _await_start(self) -> None:
        """Read stderr until sigrok-cli says the decoders' sample rate: it runs; else its error, one line."""
        deadline = time.monotonic() + START_TIMEOUT_S
        err = self.proc.stderr.fileno()
        while not self._started_decoding:
            left = deadline - time.monotonic()
            if left <= 0:
                raise CaptureError(f"{self.where}: sigrok-cli did not start decoding in {START_TIMEOUT_S:.0f} s"
                                   f"{self._why()}")
            ready, _, _ = select.select([err], [], [], min(left, 0.2))
            if ready and not self._read_stderr():
                self.proc.wait()
                raise CaptureError(f"{self.where}: sigrok-cli ended before decoding (exit {self.proc.returncode})"
                                   f"{self._why()}")

    def _why(self) -> str:
        return f": {self.errors[-1]}" if self.errors else ""

    def _read_stderr(self) -> bool:
        """Read what stderr has; False at its end."""
        try:
            data = os.read(self.proc.stderr.fileno(), 65536)
        except BlockingIOError:
            return True
        if not data:
            return False
        lines = (self._err_buf + data).split(b"\n")
        self._err_buf = lines.pop()
        for line in lines:
            self._stderr_line(line)
        return True

    def _stderr_line(self, line: bytes) -> None:
        if line.startswith(b"srd: "):
            m = _DECODING.match(line)
            if m:
                self._last_instance = m.group(1)
                return
            m = _DONE.match(line)
            if m:
                if self._last_instance == UART.encode():
                    self._pending_wm.append(int(m.group(1)))
                return
            m = _RATE_LINE.match(line)
            if m:
                rate = int(m.group(1))
                if rate != self.samplerate:
                    raise CaptureError(f"{self.where}: the analyzer runs at {rate:,} samples/s, not "
                                       f"{self.samplerate:,} (give a --samplerate it has)")
                self._started_decoding = True
                return
        if FINALIZE_CRASH in line:
            self.finalize_crash = True
        elif _ERROR.search(line):
            self.errors.append(line.decode("utf-8", "replace").strip())

    def events(self) -> Iterator:
        self.open()
        uart = self.uart
        out_fd, err_fd = self.proc.stdout.fileno(), self.proc.stderr.fileno()
        fds = [out_fd, err_fd]
        buf = b""
        stop_sent = None
        try:
            while fds:
                if self._stop.is_set() and stop_sent is None:
                    stop_sent = time.monotonic()
                    if not self._ask_stop():
                        return
                if stop_sent is not None and time.monotonic() - stop_sent > STOP_GRACE_S:
                    self.proc.terminate()  # it did not take the key: what it printed so far is kept
                    stop_sent = float("inf")
                ready, _, _ = select.select(fds, [], [], 0.2)
                if err_fd in ready and not self._read_stderr():
                    fds.remove(err_fd)
                if out_fd in fds and (out_fd in ready or self._pending_wm):
                    while True:  # drain: everything sigrok printed before its last stderr line is here
                        try:
                            data = os.read(out_fd, 1 << 16)
                        except BlockingIOError:
                            break
                        if not data:
                            fds.remove(out_fd)
                            break
                        lines = (buf + data).split(b"\n")
                        buf = lines.pop()
                        for line in lines:
                            uart.feed(line)
                for wm in self._pending_wm:  # every one, in order: each is a tick in its place
                    self.watermark = wm
                    uart.watermark(wm)
                self._pending_wm.clear()
                yield from uart.take()
            if buf:
                uart.feed(buf)
            rc = self.proc.wait()
            uart.finish()
            yield from uart.take()
            if uart.glitches:
                from sniffer.stderr import say

                say(f"note: {self.where}: {uart.glitches} start bit(s) that were not (a glitch or noise shorter than "
                    "half a bit): no byte")
            if stop_sent is None and not self._closed:
                if "--continuous" in self.acquire:  # an analyzer read continuously ends only when asked to
                    raise CaptureError(f"{self.where}: the analyzer stopped sending (sigrok-cli exit {rc}){self._why()}"
                                       "; the capture so far is kept")
                if rc != 0 and not self.finalize_crash:
                    raise CaptureError(f"{self.where}: sigrok-cli failed (exit {rc}){self._why()}")
                short = self.short_of()
                if short:
                    raise CaptureError(f"{self.where}: {short}")
        finally:
            self.close()

    def short_of(self) -> str | None:
        """Why sigrok-cli's decode of a file ended short, or None: the samples its UART decoder handled (its last
        "Done" watermark) against the samples the file holds.  sigrok-cli ends with exit 0 at a member it
        cannot read; the frames after it would be lost without a word."""
        if self.live or self.total_samples is None or self.watermark >= self.total_samples:
            return None
        done = self.watermark * 1000 // self.total_samples / 10  # rounded down: 99.96% is not 100%
        return (f"sigrok-cli stopped after sample {self.watermark:,} of the {self.total_samples:,} the file holds "
                f"({done:.1f}%; {self.total_samples - self.watermark:,} samples not decoded){self._why()}; "
                "the frames before it are kept")

    def _ask_stop(self) -> bool:
        """Stop the acquisition: a live analyzer gets sigrok-cli's "any key" (it ends cleanly); a file's decode is
        ended.  True: read on to sigrok-cli's end."""
        if self.live and self.proc.poll() is None:
            try:
                self.proc.stdin.write(b"\n")
                self.proc.stdin.flush()
                return True
            except OSError:
                pass
        self.close()
        return False

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        p, self.proc = self.proc, None
        if p is None:
            return
        self._closed = True
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(2)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in (p.stdin, p.stdout, p.stderr):
            if f is not None:
                try:
                    f.close()
                except OSError:
                    pass

    def position(self) -> tuple[int, int] | None:
        """(samples decoded, samples in the file) for a progress bar; None live."""
        if self.total_samples is None:
            return None
        return min(self.watermark, self.total_samples), self.total_samples
