"""The simulator as a session source: a live demo over a pseudo-terminal, or a capture made in-process.

DemoSource (`sniffer demo`, `sniffer serve --demo`): a PtyBus plays the
scenario's traffic at its bus times and the real read-only SerialSource reads
the other end, exactly as `sniffer live` reads an adapter.  The scenario says
the line settings, protocol and drive models (the capture's metadata layer of
the session's precedence rule).  The bus counts what the sniffer wrote back
(it must stay 0).

SimulatedSource (`sniffer simulate`): the same traffic as a logic analyzer
(per-byte times) or a USB adapter (per-read chunks) would have recorded it,
generated without waiting: the input of `simulate --out FILE.mcap|.csv`; set to
other settings than the line's (`receiver`), it records what its UART received.
"""

from __future__ import annotations

import threading

from sniffer import __version__
from sniffer.events import CaptureInfo
from sniffer.line import LineSettings
from sniffer.simulator.bus import simulate
from sniffer.simulator.chunks import usb_chunks, wire_chunks
from sniffer.simulator.received import received
from sniffer.simulator.scenario import Scenario, get_scenario

LINGER_S = 0.3  # after the last frame: time for it to reach the sniffer before the capture ends


def scenario_named(name: str) -> Scenario:
    """get_scenario with a SettingsError-style one-line error."""
    from sniffer.line import SettingsError

    try:
        return get_scenario(name)
    except ValueError as e:
        raise SettingsError(str(e)) from None


class DemoSource:
    """A simulated bus on a pty, read by the live serial source (see the module doc)."""

    def __init__(self, scenario: Scenario, seed: int = 1, duration_s: float = 15.0) -> None:
        self.scenario = scenario
        self.seed = seed
        self.duration_s = duration_s if duration_s > 0 else 24 * 3600.0
        self.stats = None  # PlayStats once the play ended
        self.bytes_written_back: int | None = None
        self._bus = None
        self._serial = None
        self._player: threading.Thread | None = None
        self._stop = threading.Event()

    def open(self) -> CaptureInfo:
        from sniffer.sources.serial_live import SerialSource
        from sniffer.simulator.ptybus import PtyBus

        sc = self.scenario
        self._bus = PtyBus()
        try:
            self._serial = SerialSource(self._bus.port, sc.line, reconnect=False, low_latency=False)
            info = self._serial.open()
        except BaseException:
            self._bus.close()
            raise
        info.protocol = sc.protocol
        info.devices = dict(sc.devices)
        info.source = f"demo:{sc.name}:seed={self.seed}"
        frames = simulate(sc, sc.line, self.duration_s, self.seed)

        def play():
            self.stats = self._bus.play(frames, stop_event=self._stop)
            if not self._stop.wait(LINGER_S):
                self._serial.stop()  # the bus is done: end the capture on silence

        self._player = threading.Thread(target=play, name="simulated-bus", daemon=True)
        self._player.start()
        return info

    @property
    def port(self) -> str | None:
        return self._bus.port if self._bus else None

    def events(self):
        return self._serial.events()

    def stop(self) -> None:
        self._stop.set()
        if self._serial is not None:
            self._serial.stop()

    def close(self) -> None:
        self.stop()
        if self._player is not None:
            self._player.join(timeout=5)
        if self._bus is not None:
            self._bus.drain()
            self.bytes_written_back = self._bus.bytes_received_from_sniffer
            self._bus.close()


class SimulatedSource:
    """A scenario's traffic as a capture device would have recorded it, generated in-process."""

    def __init__(self, scenario: Scenario, line: LineSettings, duration_s: float, seed: int = 1,
                 adapter: str = "usb", receiver: LineSettings | None = None) -> None:
        self.scenario = scenario
        self.line = line
        self.receiver = receiver  # the device was set to these (None: the line's own)
        self.duration_s = duration_s
        self.seed = seed
        self.adapter = adapter
        self._stop = False

    def open(self) -> CaptureInfo:
        if self.receiver is None:  # a wrong_line_settings fault: the device is set to something else
            from sniffer.simulator.faults import receiver_for

            self.receiver = receiver_for(self.scenario, self.line)
        sc, line = self.scenario, self.receiver or self.line
        extra = {"simulated_line": self.line.label()} if self.receiver else {}
        if sc.faults:  # what was put on the line, for whoever reads the capture later
            extra["simulated_faults"] = " ".join(f.label() for f in sc.fault_specs) if sc.fault_specs else ",".join(
                k if u is None else f"{k}:{u}" for k, u in sc.faults)
        return CaptureInfo(
            source=f"simulator:{sc.name}:seed={self.seed}", port="(simulated)", baud=line.baud,
            parity=line.parity, stopbits=line.stopbits, databits=line.databits,
            time_source="read" if self.adapter == "usb" else "byte", t0_ns=0, wall_anchor_ns=0,
            sniffer_version=__version__, low_latency={"simulated": True, "adapter": self.adapter},
            devices=dict(sc.devices), protocol=sc.protocol, extra=extra,
        )

    def events(self):
        frames = simulate(self.scenario, self.line, self.duration_s, self.seed)
        if self.receiver is not None:
            frames = received(frames, self.line, self.receiver)
        chunks = usb_chunks(frames, seed=self.seed) if self.adapter == "usb" else wire_chunks(frames)
        for ev in chunks:
            if self._stop:
                return
            yield ev

    def stop(self) -> None:
        self._stop = True


__all__ = ["DemoSource", "SimulatedSource", "scenario_named", "LINGER_S"]
