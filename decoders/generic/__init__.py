"""Generic Modbus decoder (every standard function code, no register names)."""

from .decoder import GenericModbus

__all__ = ["GenericModbus"]
