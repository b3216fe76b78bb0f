"""The live views both the HTTP routes and the websocket pages serve: rungs as SVG with
their values, the simulated devices, the trace recorder's samples."""

from __future__ import annotations

import json
import math
from typing import Any

from ..address import Ref
from . import ladderview, machineview
from .control import ApiError, Controller
from .machineview import FE_WINDOW_MAX

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
        self._fe_since = -1.0  # machine time of the last devices_now (FE envelopes start there)
        self._titles: tuple[Any, dict[int, str]] = (None, {})

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
        """The machine's state of one scan (called in the scan thread): each device's status
        with, under "view", what its drawing needs (machineview); the active Grafcet steps;
        the estimator's words on a machine with a scope."""
        plc = self.ctl.plc
        since = self._fe_since if 0 <= plc.time - self._fe_since <= FE_WINDOW_MAX \
            else plc.time - FE_WINDOW_MAX
        self._fe_since = plc.time
        out: dict[str, Any] = {}
        scope = False
        for name, dev in plc.devices.items():
            st = dict(dev.status())
            st["type"] = kind = getattr(dev, "type_name", "device")
            scope = scope or kind == "scope"
            for attr in ("travel", "steps_per_unit"):
                if hasattr(dev, attr):
                    st[attr] = getattr(dev, attr)
            view = machineview.device_view(dev, since)
            if view is not None:
                st["view"] = view
            out[name] = st
        snap: dict[str, Any] = {"devices": out, "time": plc.time}
        titles = self._step_titles()
        if titles:
            x = plc.mem.x
            snap["steps"] = {"active": [n for n in sorted(titles) if x[n]],
                             "titles": {str(n): t for n, t in titles.items()}}
        if scope:
            snap["estimate"] = machineview.estimate(plc)
        return snap

    def _step_titles(self) -> dict[int, str]:
        plc = self.ctl.plc
        if self._titles[0] != plc.program_version:
            self._titles = (plc.program_version, machineview.step_titles(plc.rungs))
        return self._titles[1]

    def machine_view(self, snap: dict[str, Any], since: int) -> dict[str, Any]:
        """`snap` (devices_now's) with the trace recorder's samples from `since`."""
        trace = self.ctl.plc.trace
        n = len(trace)
        chunk = [list(s) for s in trace[since:min(n, since + TRACE_CHUNK)]]
        return snap | {"trace_from": since, "trace": chunk, "trace_total": n}


__all__ = ["LiveViews", "clean", "dumps"]
