"""A slave's driver-enable timing on its frames (sans-I/O): when its transceiver took the bus, when it let go.

A logic capture with `--de` (sources/sigrok_uart.py) hands the bytes the slave
sent while its driver was enabled in Chunks carrying `de = (rise, fall)`: that
DE window's edges in ns.  The pipeline notes each window (`note`) and marks
the frames it settles (`mark`):

* `Frame.de_on_ns`  = DE rise - the start of the frame's first start bit, on
  the window's first frame: below 0 the driver was on before the start bit; above
  0 it came on late (the first bits went out on an undriven bus);
* `Frame.de_off_ns` = DE fall - the end of the frame's last stop bit, on the
  window's last frame: above 0 the driver held the bus after the stop bit; below
  0 it let go early (the stop bit was cut).

A window whose rise came before the capture began has no de_on_ns; one whose
fall never came (the capture ended, DE stuck high) no de_off_ns.
"""

from __future__ import annotations

from sniffer.events import Chunk

KEEP = 16  # windows remembered: frames settle a window or two after their bytes


class DriverEnable:
    def __init__(self, char_ns: int) -> None:
        self.char_ns = char_ns
        self.windows: dict = {}  # (channel, rise or first byte) -> [rise, fall, first byte ns, last byte ns]

    def note(self, c: Chunk) -> None:
        rise, fall = c.de
        bt = c.byte_t_ns
        if not bt:
            return
        key = (c.channel, rise if rise is not None else "start")
        w = self.windows.get(key)
        if w is None:
            self.windows[key] = [rise, fall, bt[0], bt[-1]]
            if len(self.windows) > KEEP:
                del self.windows[next(iter(self.windows))]
        else:
            w[3] = bt[-1]
            if fall is not None:
                w[1] = fall

    def mark(self, frames) -> None:
        char = self.char_ns
        for f in frames:
            for (channel, _), (rise, fall, first, last) in self.windows.items():
                if channel != f.channel or not first <= f.t_ns <= last:
                    continue
                if f.t_ns == first and rise is not None:
                    f.de_on_ns = rise - f.t_ns
                if f.t_end_ns - char == last and fall is not None:
                    f.de_off_ns = fall - f.t_end_ns
                break
