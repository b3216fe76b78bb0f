"""What the Machine tab draws, per device family rather than per program: each device's
status plus the geometry a drawing needs (`view`), the program's active Grafcet steps, and,
for a machine with a scope (the mass-estimation family), the host's estimate words.

Runs in the scan thread (`Reading.sample`), between two scans: plain attribute and memory
reads only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..access import DeviceEntry
from ..address import Ref, parse_address
from ..il.ast import Grafcet

FE_WINDOW_MAX = 1.0  # s of machine time an FE envelope covers at most (a page's first one)


def _finite(v: float) -> float | None:
    return v if math.isfinite(v) else None


def servo_view(dev: Any, since_t: float) -> dict[str, Any]:
    """A servo axis in its true frame (counts from the home index mark, as the trace
    recorder and the limit switches use): position, commanded position, travel, FE and
    its envelope over the servo-rate trace since `since_t` (machine time)."""
    g = dev.opt.geometry
    lo = g.limit_minus if g.limit_minus is not None else g.hard_stop_minus
    hi = g.limit_plus if g.limit_plus is not None else g.hard_stop_plus
    x = float(dev.axis_position())
    fe = float(dev.fe) if dev.closed else 0.0
    fe_lo = fe_hi = fe
    trace = dev.trace
    if trace:  # rows (tick, commanded, actual, output); ticks of dev.T seconds
        first = math.ceil(since_t / dev.T)
        n = 0
        for k, cp, ap, _u in reversed(trace):
            if k < first or n >= 20000:
                break
            e = cp - ap
            fe_lo, fe_hi = min(fe_lo, e), max(fe_hi, e)
            n += 1
    return {"counts_per_mm": dev.opt.counts_per_mm, "x": x, "cmd": x + fe,
            "lo": _finite(lo) if lo is not None else None,
            "hi": _finite(hi) if hi is not None else None,
            "fe": fe, "fe_lo": fe_lo, "fe_hi": fe_hi, "fe_max": float(dev.fe_max),
            "v": float(dev.v), "enabled": bool(dev.closed),
            "load_mass_ratio": float(dev.load_mass_ratio)}


def stepper_view(dev: Any) -> dict[str, Any]:
    return {"steps_per_unit": dev.steps_per_unit, "travel": dev.travel}


def trace_view(dev: Any) -> dict[str, Any]:
    axes = list(dev.options.axes)
    return {"axes": axes, "pen": dev.options.pen, "samples": len(dev.samples)}


def device_view(dev: Any, since_t: float, kind: str) -> dict[str, Any] | None:
    """What the drawing of a device of type `kind` needs (None: no drawing)."""
    if kind == "servo_axis":
        return servo_view(dev, since_t)
    if kind == "stepper":
        return stepper_view(dev)
    if kind == "trace":
        return trace_view(dev)
    return None


def device_status(entry: DeviceEntry, since_t: float) -> dict[str, Any]:
    """A device's status, its type, a stepper's geometry (the page scales its axis by
    them) and, under "view", what its drawing needs."""
    dev, kind = entry.device, entry.kind
    st = dict(dev.status()) | {"type": kind}
    if kind == "stepper":
        st |= stepper_view(dev)
    view = device_view(dev, since_t, kind)
    if view is not None:
        st["view"] = view
    return st


def step_titles(rungs: list[Any]) -> dict[int, str]:
    """{step: the title of the rung that opens it} for a Grafcet program ({} otherwise)."""
    out: dict[int, str] = {}
    for r in rungs:
        for ins in r.instructions[:1]:
            if isinstance(ins, Grafcet) and ins.op in ("=*=", "-*-") and ins.step is not None:
                out[ins.step] = r.title
    return out


def estimate(read: Callable[[list[Ref]], list[Any]], profile: Any) -> dict[str, Any]:
    """The mass estimator's handshake words (massest/handshake.py is their one place),
    read by `read` (the access port's `read_now`)."""
    from ..massest import handshake as hs

    def word(n: int) -> int:
        return int(read([parse_address(f"%MW{n}", profile)])[0])

    def real(n: int) -> float | None:
        return _finite(float(read([parse_address(f"%MF{n}", profile)])[0]))

    return {"state": word(hs.W_STATE), "requests": word(hs.W_REQ), "answers": word(hs.W_ACK),
            "status": word(hs.W_STATUS), "row": word(hs.W_ROW), "mass_kg": real(hs.F_MASS),
            "uncertainty_kg": real(hs.F_UNCERT), "accel": real(hs.F_ACCEL)}


__all__ = ["device_status", "device_view", "estimate", "step_titles"]
