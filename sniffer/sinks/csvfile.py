"""CSV export: OUT.csv (one row per frame) + OUT.points.csv (one row per decoded point); see rows.py."""

from __future__ import annotations

import csv

from ..events import CaptureInfo
from ..frame import Frame
from .base import Sink
from .rows import FRAME_COLUMNS, POINT_COLUMNS, frame_row, point_rows

BATCH = 4096  # rows written at once (csv.writer.writerows is C: one call per batch)


class CsvSink(Sink):
    """Empty cells for None; booleans as True/False."""

    def __init__(self, frames_path: str, points_path: str) -> None:
        self._ff = open(frames_path, "w", newline="", encoding="utf-8")
        try:
            self._fp = open(points_path, "w", newline="", encoding="utf-8")
        except BaseException:
            self._ff.close()
            raise
        self._wf = csv.writer(self._ff)
        self._wp = csv.writer(self._fp)
        self._rf: list[tuple] = []
        self._rp: list[tuple] = []
        self._t0 = 0
        self._anchor = 0
        self.frames = 0

    def start(self, info: CaptureInfo) -> None:
        self._t0, self._anchor = info.t0_ns, info.wall_anchor_ns
        self._wf.writerow(FRAME_COLUMNS)
        self._wp.writerow(POINT_COLUMNS)
        self._ff.flush()  # a disk that is full already fails now, before the input is read
        self._fp.flush()

    def frame(self, f: Frame) -> None:
        self._rf.append(frame_row(f, self._t0, self._anchor))
        if f.points:
            self._rp.extend(point_rows(f, self._t0))
        self.frames += 1
        if len(self._rf) >= BATCH or len(self._rp) >= BATCH:
            self._flush()

    def _flush(self) -> None:
        self._wf.writerows(self._rf)
        self._wp.writerows(self._rp)
        self._rf, self._rp = [], []

    def close(self) -> None:
        try:
            self._flush()
        finally:
            self._ff.close()
            self._fp.close()
