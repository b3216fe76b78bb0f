"""What the Machine tab draws, per device rather than per program: each device's status
plus what its drawing needs (its `view()`), the panels devices describe of themselves (the
mass estimator's words beside a machining centre's scope) and the program's active Grafcet
steps. The web monitor imports no machine: a machine's devices describe themselves.

Runs in the scan thread (`Reading.sample`), between two scans: plain attribute and memory
reads only.
"""

from __future__ import annotations

from typing import Any

from softplc.access import DeviceEntry
from softplc.il.ast import Grafcet

FE_WINDOW_MAX = 1.0  # s of machine time an FE envelope covers at most (a page's first one)


def device_status(entry: DeviceEntry, since_t: float) -> dict[str, Any]:
    """A device's status, its type and, under "view", what its drawing needs."""
    dev, kind = entry.device, entry.kind
    st = dict(dev.status()) | {"type": kind}
    view = dev.view(since_t)
    if view is not None:
        st["view"] = view
    return st


def panels(entries: list[DeviceEntry]) -> dict[str, Any]:
    """The panels the machine's devices describe, by name (the first device wins a name)."""
    out: dict[str, Any] = {}
    for entry in entries:
        for name, panel in entry.device.panels().items():
            out.setdefault(name, panel)
    return out


def step_titles(rungs: list[Any]) -> dict[int, str]:
    """{step: the title of the rung that opens it} for a Grafcet program ({} otherwise)."""
    out: dict[int, str] = {}
    for r in rungs:
        for ins in r.instructions[:1]:
            if isinstance(ins, Grafcet) and ins.op in ("=*=", "-*-") and ins.step is not None:
                out[ins.step] = r.title
    return out


__all__ = ["FE_WINDOW_MAX", "device_status", "panels", "step_titles"]
