"""The host access port: one way for every host front-end (web monitor, `softplc io`
through it, the debugger's data commands, Modbus for its typed writes) into a running
controller. Below modbus/web/debug, above the PLC facade.

`AccessPort` (port.py): typed reads, checked writes/forces/unforces/control commands as
records on one bounded queue applied at the scan boundary (commands.py), a status record;
`RunState` is the run-state enum (runtime/runstate.py).
"""

from __future__ import annotations

from ..runtime.runstate import RunState
from .commands import ACTIONS, Action
from .errors import AccessError
from .machine import DeviceEntry
from .port import AccessPort, Status

__all__ = ["ACTIONS", "AccessError", "AccessPort", "Action", "DeviceEntry", "RunState",
           "Status"]
