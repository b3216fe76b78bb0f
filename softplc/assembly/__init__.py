"""The machine builder: program + configuration -> the assembled parts of a soft Twido.

`assemble(config, clock)` loads and checks the configuration and builds the controller's
parts (memory image, expansion modules, analog channels, constants, EXCH port, engine);
`equip` adds the function blocks and the simulated machine (`attach_devices`), and raises
every problem of the build at once; `load_program` resolves, allocates, binds and
compiles a program onto them. The result is
one typed record, `Machine`; `softplc.plc.PLC` is the facade over it (run control, item
access).
"""

from __future__ import annotations

from softplc.assembly.compile import compile_onto, forced_bits, load_program
from softplc.assembly.machine import (
    ConfigSource,
    Loaded,
    Machine,
    application_id,
    assemble,
    attach_devices,
    attach_scan_hooks,
    equip,
    load,
    settle_exchange,
    symbol_table,
)

__all__ = ["ConfigSource", "Loaded", "Machine", "application_id", "assemble", "attach_devices",
           "attach_scan_hooks", "compile_onto", "equip", "forced_bits", "load", "load_program",
           "settle_exchange", "symbol_table"]
