"""softplc: a soft-PLC that runs Telemecanique Twido Instruction List programs."""

from .errors import (
    AddressError,
    CompileError,
    ConfigError,
    Diagnostic,
    ParseError,
    ProgramError,
    SoftPLCError,
)
from .plc import PLC

__all__ = ["PLC", "ProgramError", "ParseError", "CompileError", "ConfigError", "AddressError",
           "Diagnostic", "SoftPLCError"]
__version__ = "0.1.0"
