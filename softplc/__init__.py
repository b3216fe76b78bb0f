"""softplc: a soft-PLC that runs Telemecanique Twido Instruction List programs."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from softplc.errors import (
    AddressError,
    CompileError,
    ConfigError,
    Diagnostic,
    ParseError,
    ProgramError,
    SoftPLCError,
)

if TYPE_CHECKING:
    from softplc.plc import PLC

__all__ = ["PLC", "ProgramError", "ParseError", "CompileError", "ConfigError", "AddressError",
           "Diagnostic", "SoftPLCError"]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    """`softplc.PLC` imported on first use (PEP 562): it pulls in the compiler and pydantic,
    which `softplc --help` and the light commands do not need."""
    if name == "PLC":
        from softplc.plc import PLC

        return PLC
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
