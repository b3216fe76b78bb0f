"""The live views both the HTTP routes and the websocket pages serve: rungs as SVG with
their values, the simulated devices, the trace recorder's samples."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from softplc.twido.address import Ref
from softplc.web import ladderview, machineview
from softplc.web.control import ApiError, Controller
from softplc.web.machineview import FE_WINDOW_MAX

TRACE_CHUNK = 20000  # trace samples looked at per update at most: a new page catches up
# over a few updates (a 100000-sample piece in about half a second at UPDATE_HZ); the ones
# sent are thinned to the drawing's resolution (`thin`)
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
        m = self.ctl.machine
        rungs = m.rungs
        if not 0 <= n < len(rungs):
            raise ApiError(f"rung {n}: the program has rungs 0..{len(rungs) - 1}", 404)
        key = (m.code_version, n)
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
        m = self.ctl.machine
        forced = set(self.ctl.port.forced)
        key = (m.code_version, n, repr(sorted(values.items(), key=lambda kv: str(kv[0]))),
               tuple(sorted(forced)))
        svg = self._svg_cache.get(key)
        if svg is None:
            if len(self._svg_cache) > SVG_CACHE:
                self._svg_cache.clear()
            svg = self._svg_cache[key] = ladderview.render(m.rungs[n], values, forced)
        return svg

    def devices_now(self) -> dict[str, Any]:
        """The machine's state of one scan (called in the scan thread): each device's status
        with, under "view", what its drawing needs (machineview); the active Grafcet steps;
        the panels its devices describe (the estimator's words beside a scope)."""
        m, port = self.ctl.machine, self.ctl.port
        now = m.time
        since = self._fe_since if 0 <= now - self._fe_since <= FE_WINDOW_MAX \
            else now - FE_WINDOW_MAX
        self._fe_since = now
        out = {d.name: machineview.device_status(d, since) for d in m.devices}
        snap: dict[str, Any] = {"devices": out, "time": now}
        titles = self._step_titles()
        if titles:
            steps = sorted(titles)
            active = port.read_now([Ref("X", n) for n in steps])
            snap["steps"] = {"active": [n for n, on in zip(steps, active, strict=True) if on],
                             "titles": {str(n): t for n, t in titles.items()}}
        snap |= machineview.panels(m.devices)
        return snap

    def _step_titles(self) -> dict[int, str]:
        m = self.ctl.machine
        if self._titles[0] != m.code_version:
            self._titles = (m.code_version, machineview.step_titles(m.rungs))
        return self._titles[1]

    def machine_view(self, snap: dict[str, Any], since: int) -> dict[str, Any]:
        """`snap` (devices_now's) with the trace recorder's samples from `since` up to
        `trace_next` (the next call's `since`), thinned to the recorder's `cell`."""
        trace = self.ctl.machine.trace
        n = len(trace)
        end = min(n, since + TRACE_CHUNK)
        rows = trace[since:end]
        cell = next((d["view"]["cell"] for d in snap.get("devices", {}).values()
                     if d.get("type") == "trace" and "cell" in d.get("view", {})), None)
        if cell is not None:
            rows = thin(rows, cell)
        return snap | {"trace_from": since, "trace": [list(s) for s in rows],
                       "trace_next": end, "trace_total": n}


def thin(rows: list[Any], cell: list[float]) -> list[Any]:
    """The samples (t, x, z, pen, ...) a drawing at `cell` resolution (x, z) needs: those
    that enter another cell or change the pen, the one before a pen change, the first and
    the last; a long run inside one cell (a slow move, a dwell) is one sample."""
    if len(rows) < 3 or min(cell) <= 0:
        return rows
    a = np.asarray([r[1:4] for r in rows], dtype=float)
    q = np.floor(a[:, :2] / np.asarray(cell, dtype=float))
    pen = np.diff(a[:, 2]) != 0
    moved = (np.diff(q, axis=0) != 0).any(axis=1) | pen
    keep = np.ones(len(rows), dtype=bool)
    keep[1:-1] = moved[:-1] | pen[1:]  # sample i: entered from i-1, or the pen changes after
    return [rows[i] for i in np.flatnonzero(keep)]


__all__ = ["LiveViews", "clean", "dumps", "thin"]
