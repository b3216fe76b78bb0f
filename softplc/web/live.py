"""The live views both the HTTP routes and the websocket pages serve: rungs as SVG with
their values, the simulated devices, the trace recorder's samples."""

from __future__ import annotations

import json
import math
from typing import Any

from ..address import Ref
from . import ladderview
from .control import ApiError, Controller

TRACE_CHUNK = 5000  # trace samples per update at most: a new page catches up over a few
SVG_CACHE = 256  # rendered rungs kept (by program version, rung, values, forced objects)


def clean(v: Any) -> Any:
    """NaN and infinities (a float word can hold them) as strings: JSON has no such numbers."""
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    if isinstance(v, dict):
        return {k: clean(x) for k, x in v.items()}
    if isinstance(v, list):
        return [clean(x) for x in v]
    return v


def dumps(v: Any) -> str:
    return json.dumps(clean(v), allow_nan=False, default=str)


class LiveViews:
    def __init__(self, controller: Controller):
        self.ctl = controller
        self._rung_refs: dict[tuple[int, int], list[Ref]] = {}
        self._svg_cache: dict[Any, str] = {}

    def refs_of(self, n: int) -> list[Ref]:
        """The objects rung `n` shows (404 for a rung the program does not have)."""
        plc = self.ctl.plc
        rungs = plc.rungs
        if not 0 <= n < len(rungs):
            raise ApiError(f"rung {n}: the program has rungs 0..{len(rungs) - 1}", 404)
        key = (plc.program_version, n)
        refs = self._rung_refs.get(key)
        if refs is None:
            refs = self._rung_refs[key] = ladderview.refs(rungs[n])
        return refs

    async def ladders(self, wanted: set[int]) -> dict[int, str]:
        refs = {n: self.refs_of(n) for n in wanted}
        readers = {n: self.ctl.reading.reader(r) for n, r in refs.items()}
        raw = await self.ctl.reading.sample(lambda: {n: read() for n, read in readers.items()})
        return {n: self.svg(n, ladderview.capture(refs[n], raw[n])) for n in wanted}

    def svg(self, n: int, values: dict[Ref, Any]) -> str:
        plc = self.ctl.plc
        forced = set(plc.forced)
        key = (plc.program_version, n, repr(sorted(values.items(), key=lambda kv: str(kv[0]))),
               tuple(sorted(forced)))
        svg = self._svg_cache.get(key)
        if svg is None:
            if len(self._svg_cache) > SVG_CACHE:
                self._svg_cache.clear()
            svg = self._svg_cache[key] = ladderview.render(plc.rungs[n], values, forced)
        return svg

    def devices_now(self) -> dict[str, Any]:
        out = {}
        for name, dev in self.ctl.plc.devices.items():
            st = dict(dev.status())
            st["type"] = getattr(dev, "type_name", "device")
            for attr in ("travel", "steps_per_unit"):
                if hasattr(dev, attr):
                    st[attr] = getattr(dev, attr)
            out[name] = st
        return out

    def machine_view(self, devices: dict[str, Any], since: int) -> dict[str, Any]:
        trace = self.ctl.plc.trace
        n = len(trace)
        chunk = [list(s) for s in trace[since:min(n, since + TRACE_CHUNK)]]
        return {"devices": devices, "trace_from": since, "trace": chunk,
                "trace_total": n}


__all__ = ["LiveViews", "clean", "dumps"]
