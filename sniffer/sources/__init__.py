"""Sources of timestamped bytes: live serial, MCAP, byte CSV, Saleae CSV.

Every source gives a CaptureInfo and an iterator of events (Chunk / Tick / Gap).
"""

from __future__ import annotations


class CaptureError(Exception):
    """A capture file that cannot be read: one clear line for the user, exit code 2."""
