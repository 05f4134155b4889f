"""Tek-Drive TDS-V8 (both manual revisions): register map + the DRV/PRG write rule."""

from .schema import TdsV8Decoder, load

__all__ = ["TdsV8Decoder", "load"]
