"""A machine's IL program parsed once per process, for the modules that build many PLCs of
it (a parsed program is never changed: each PLC compiles and runs its own; parsing was
about half of building the cutting table's, 0.05 of 0.085 CPU-s)."""

from __future__ import annotations

import functools
from pathlib import Path

from softplc.assembly.machine import symbol_table
from softplc.il.ast import Program
from softplc.il.parser import parse_file


@functools.cache
def parsed(il: Path, toml: Path) -> Program:
    """`il` parsed with the symbols of `toml`: only for configurations whose symbols are
    that file's (a test that changes a device or a constant, not a symbol)."""
    return parse_file(il, symbol_table(toml))
