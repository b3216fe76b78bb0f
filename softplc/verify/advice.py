"""What `softplc verify` says beside a verdict: for an UNKNOWN, what to try next; for a
PROVEN, whether it rests on an object that never changes (held at its cold-start value),
checked by searching again with that object free."""

from __future__ import annotations

import math
from typing import Any

import z3

from softplc.twido.address import parse_address
from softplc.verify.checker import Checker
from softplc.verify.clock import Clock, TimeUp
from softplc.verify.engines import Limits, Result, bmc
from softplc.verify.guard import isolated
from softplc.verify.model import Model
from softplc.verify.requirements import Requirement, Spec

US_PER_MS = 1000
US_PER_S = 1_000_000
LONGEST_PERIOD_US = 60_000_000  # `parse_periods`: a scan period range ends within 1 min
VACUITY_SHARE = 0.5  # of a requirement's time, for the search with held objects free


def _ms(us: int) -> str:
    """A duration as the configuration writes it: 10ms, 3s."""
    return f"{us // US_PER_S}s" if us % US_PER_S == 0 else f"{us / US_PER_MS:g}ms"


def unknown_hints(model: Model, res: Result, limits: Limits) -> list[str]:
    """What to try after an UNKNOWN: a depth the timers need, a scan period range, the
    loop bound, a larger k or more time."""
    tips: list[str] = []
    period = model.period_us
    reach = max(res.depth, limits.depth) * model.longest_us
    long = sorted(((int(t.P) * t.base_us, name) for name, t in model.timers.items()
                   if reach < int(t.P) * t.base_us <= LONGEST_PERIOD_US), reverse=True)
    if long:  # the preset of the longest: the time it must see elapse
        span_us, name = long[0]
        scans = math.ceil(span_us / model.longest_us)
        longest = min(LONGEST_PERIOD_US, math.ceil(span_us / period) * period)
        others = f" (and {len(long) - 1} other timer(s))" if len(long) > 1 else ""
        tips.append(f"{name}{others} needs {scans} scans of {_ms(model.longest_us)} to "
                    f"elapse, more than the {limits.depth} searched: try --depth "
                    f"{scans + 2}, or let the scan period vary: [environment] scan_period = "
                    f'["{_ms(period)}", "{_ms(longest)}"] (--scan-period '
                    f"{_ms(period)}:{_ms(longest)})")
    if model.loops.sites:
        tips.append(f"a loop is unrolled {model.loops.bound} passes per scan: "
                    f"--loop-bound {model.loops.bound * 2} if it runs more")
    if "time" in res.note or "ran out" in res.note:
        tips.append(f"more time: --timeout {limits.seconds * 2:g}")
    elif res.depth >= limits.depth:
        tips.append(f"a deeper search: --depth {limits.depth * 2}; a proof by induction: "
                    f"--max-k {limits.max_k * 2}, or an `always` requirement that "
                    "strengthens it listed before it (proven ones are used as lemmas)")
    return tips


def vacuity(model: Model, spec: Spec, req: Requirement, limits: Limits,
            loop_bound: int) -> tuple[list[str], Result | None]:
    """The held objects (`model.env.held`) a proof of `req` reads, and, when freeing them
    breaks it, the counterexample (within `limits.depth` scans, half its time)."""
    held = list(model.env.held)
    if not held:
        return [], None
    cone = set(Checker(model, spec, req).state_keys())
    keys = [k for k in held if k in cone]
    if not keys:
        return [], None
    profile = model.plc.profile
    free = [*model.env.free, *keys]  # what was free stays free: only more behaviours
    freed = Model(model.plc, spec.reads, spec.host + [parse_address(k, profile) for k in free],
                  spec.periods, loop_bound, devices={})
    ck = Checker(freed, spec, req)
    seconds = limits.seconds * VACUITY_SHARE

    def work(_report: Any) -> Result:
        try:
            return bmc(ck, limits.depth, Clock(seconds), [])
        except TimeUp as e:
            return Result("UNKNOWN", "BMC", note=str(e))
    res = isolated(work, seconds)
    return keys, res if res.status == "VIOLATED" else None


PIN_CHECK_S = 5.0  # s the solver may spend per input deciding whether the assumptions pin it


def pinned_inputs(model: Model, spec: Spec) -> list[str]:
    """Inputs the assumptions hold at one value in every scan (`assume = ["NOT %I0.0"]`):
    a proof then never sees them change, as if they were held. Each is `key=value`."""
    if not spec.assumptions or not spec.requirements:
        return []
    ck = Checker(model, spec, spec.requirements[0])
    pre, inp = model.fresh("pin")
    pre = {**model.init_state(), **pre}  # any state (the invariants bound it)
    post = model.scan(pre, inp)
    base = [*model.invariants(pre), *ck.assumed(post, inp)]
    out = []
    for key, (sort, _lo, _hi) in sorted(model.inputs.items()):
        if sort != "bool" or model.abstract.is_input(key):
            continue
        s = z3.Solver()
        s.set("timeout", int(PIN_CHECK_S * 1000))
        s.add(*base)
        can = [s.check(inp[key] == z3.BoolVal(v)) != z3.unsat for v in (False, True)]
        if can.count(True) == 1:
            out.append(f"{key}={can.index(True)}")
    return out
