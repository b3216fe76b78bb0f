"""Counterexample-guided refinement of the abstractions (`abstract`).

A counterexample of a model with abstracted objects chose their values itself. Before it
is reported, its real inputs (inputs, host words, free system objects, the scan periods:
everything but the abstracted values) are replayed in the scan engine, cold-started from
the same program and configuration, and the requirement evaluated on the engine's values.
If the engine breaks it at the same scan the counterexample stands, shown with the
engine's values. If not, the abstracted values were impossible there: the engine is
deterministic, so for those real inputs the requirement holds at that scan, and that is
added to the search as a constraint (the engine's run on those inputs, as a fact) before it
searches again. It ends with a counterexample the engine confirms, a clean depth, or the
requirement's time (UNKNOWN, saying how many were excluded)."""

from __future__ import annotations

from typing import Any

import z3

from softplc.verify.model import Model, is_object
from softplc.verify.symbolic import value_of

MS_PER_S = 1000


def real_inputs(model: Model, raw: dict[str, int]) -> dict[str, Any]:
    """A scan's inputs as the replay sets them: abstracted values left out (the engine
    computes them), the variable period as `period_ms`."""
    ins: dict[str, Any] = {k: v for k, v in raw.items() if not model.abstract.is_input(k)}
    if "_dt" in ins:  # a variable period: this scan's, in ms
        p = ins.pop("_dt") * model.period_us / MS_PER_S
        ins["period_ms"] = int(p) if p == int(p) else p
    return ins


def engine_run(model: Model, check: str, scans: list[dict[str, Any]]
               ) -> tuple[int | None, list[dict[str, int]]]:
    """The scan at which the engine breaks `check` on these real inputs (None: it does not
    within them) and every object's engine value after each scan."""
    from softplc.plc import PLC
    from softplc.verify.replay import first_failure, set_inputs
    with PLC(model.plc.ast, model.plc.config, devices=False) as plc:
        failed = first_failure(plc, check, scans)
    rows = []
    with PLC(model.plc.ast, model.plc.config, devices=False) as plc:
        keys = [k for k in model.vars if is_object(k)]
        for ins in scans[:failed or len(scans)]:
            set_inputs(plc, ins)
            plc.scan()
            rows.append({k: int(plc[k]) for k in keys})
    return failed, rows


def confirmed(model: Model, check: str, given: list[dict[str, int]]) -> bool:
    """The engine breaks `check` at the counterexample's last scan (not before: the
    abstraction is sound, so the engine cannot break it earlier than the model)."""
    failed, _ = engine_run(model, check, [real_inputs(model, g) for g in given])
    return failed == len(given)


def exclusion(model: Model, inputs: list[dict[str, Any]], m: z3.ModelRef) -> Any:
    """The constraint the engine's run adds: not these real inputs, scan by scan (for them
    the requirement holds at this depth)."""
    same = [v == m.eval(v, model_completion=True) for inp in inputs
            for k, v in inp.items() if not model.abstract.is_input(k)]
    return z3.Not(z3.And(*same)) if same else z3.BoolVal(False)


def given_inputs(inputs: list[dict[str, Any]], m: z3.ModelRef) -> list[dict[str, int]]:
    return [{k: value_of(m, v) for k, v in inp.items()} for inp in inputs]
