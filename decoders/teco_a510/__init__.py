"""TECO A510: register map + the 0.01 Hz / 0.1 Hz frequency resolution rule."""

from .schema import A510Decoder, load, load_high_frequency

__all__ = ["A510Decoder", "load", "load_high_frequency"]
