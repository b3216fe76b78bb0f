"""The host access port: one way for every host front-end (web monitor, `softplc io`
through it, the debugger's data commands; Modbus lends it its image for %MW/%M writes)
into a running controller. Below modbus/web/debug, above the PLC facade.

`AccessPort` (port.py): typed reads, checked writes/forces/unforces/control commands as
records on one bounded queue applied at the scan boundary (commands.py), a status record;
`RunState` is the run-state enum (runtime/runstate.py).

The names are loaded on first use, so that `softplc.access.commands` (the command names)
stays light for the command line (`softplc io --help` imports no PLC).
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what the names are, for type checkers
    from softplc.access.commands import ACTIONS, Action
    from softplc.access.errors import AccessError
    from softplc.access.machine import DeviceEntry
    from softplc.access.port import AccessPort, Status
    from softplc.runtime.runstate import RunState

_WHERE = {"ACTIONS": "commands", "Action": "commands", "AccessError": "errors",
          "DeviceEntry": "machine", "AccessPort": "port", "Status": "port",
          "RunState": "..runtime.runstate"}


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    mod = import_module(("." + where) if not where.startswith(".") else where, __name__)
    return getattr(mod, name)


__all__ = ["ACTIONS", "AccessError", "AccessPort", "Action", "DeviceEntry", "RunState",
           "Status"]
