"""The web API without HTTP: what the web page, `softplc io` and scripts can read and
do, over the access port (`softplc.access`), which checks, queues and reads at the scan
boundary. This adds only what is the web monitor's own: its read-only flag, the program's
name, the daemon's figures in the status, and the JSON of /api/info, /api/status and
/api/io.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from softplc.access import ACTIONS, AccessPort
from softplc.compiler.resolve import rung_uses
from softplc.il.printer import format_instruction
from softplc.twido.address import Ref
from softplc.web.errors import ApiError

MAX_PAGES = 32  # websocket pages open at once (--web-max-pages; [web] max_pages default)
READ_ONLY = "the web monitor is read-only (--web-read-only)"



def _uses(rung: Any) -> list[str]:
    """The objects a rung uses, each with its whole object (%TM0 for %TM0.Q, %MW3 for
    %MW3:X2): what the ladder's find box matches symbols against."""
    out: dict[str, None] = {}
    for ref, _, _ in rung_uses(rung):
        out[str(ref)] = None
        out[str(Ref(ref.kind, ref.index, ref.module, ref.channel))] = None
    return list(out)

class Controller:
    """The web monitor's core over an `AccessPort` it owns (closed with it)."""

    def __init__(self, port: AccessPort, *, read_only: bool = False,
                 program_name: str = "",
                 status_extra: Callable[[], dict[str, Any]] | None = None):
        self.port = port
        self.read_only = read_only
        # the objects each rung uses, for the program they were listed for (20-25 ms for a
        # machine program's 100-150 rungs: once per program, not per /api/info)
        self._uses: tuple[Any, list[list[str]]] = (None, [])
        if read_only:
            port.refuse_changes = READ_ONLY
        self.program_name = program_name
        self.status_extra = status_extra or (lambda: {})
        self.objects = port.objects  # addresses -> objects
        self.reading = port.reading  # typed reads at a scan boundary
        self.machine = port.machine

    def close(self) -> None:
        self.port.close()

    @property
    def pending(self) -> int:
        return self.port.pending

    def info(self) -> dict[str, Any]:
        m = self.machine
        if self._uses[0] is not m.rungs:  # a new program
            self._uses = (m.rungs, [_uses(r) for r in m.rungs])
        rungs = [{"index": r.index, "title": r.title or "", "section": r.section,
                  "subroutine": r.subroutine, "label": r.label,
                  "il": "\n".join(format_instruction(i) for i in r.instructions),
                  "uses": uses}
                 for r, uses in zip(m.rungs, self._uses[1], strict=True)]
        return {"program": self.program_name, "profile": self.port.profile.name,
                "io_used": m.io_used(), "period_ms": round(m.scan_period * 1000, 3),
                "modules": m.io_layout(), "device_io": m.device_io,
                "devices": {d.name: d.kind for d in m.devices}, "rungs": rungs,
                "read_only": self.read_only, "actions": list(ACTIONS),
                "analog": m.analog_channels()}

    def status(self) -> dict[str, Any]:
        return self.port.status().as_dict() | self.status_extra()

    async def io(self) -> dict[str, Any]:
        """Every I/O channel of one scan: value, forced, driving device; analog channels."""
        m = self.machine
        read_io, read_analog = self.reading.values_fn(m.io_refs()), m.analog_values_fn()
        values, analog = await self.reading.sample(lambda: (read_io(), read_analog()))
        forced = self.port.forced
        return {"modules": m.io_layout(),
                "io": {name: {"value": v, "forced": name in forced,
                              "driven_by": m.device_io.get(name, "")}
                       for name, v in values.items()},
                "analog": {ch["address"]: ch | analog[ch["address"]]
                           | {"forced": ch["address"] in forced}
                           for ch in m.analog_channels()}}


__all__ = ["MAX_PAGES", "READ_ONLY", "ApiError", "Controller"]
