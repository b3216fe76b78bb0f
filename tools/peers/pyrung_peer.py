"""softplc vs pyrung (a Python ladder simulator, PyPI `pyrung`): us per scan, same logic.

Both sides: build the program, `warmup` scans untimed, then best of `repeat` runs of
`scans` scans, the two sides' runs alternating, with the same fixed dt (softplc: virtual
clock, scan_period; pyrung: PLC(dt=...), its default history settings). pyrung is driven
through its public API (`PLC.step()`).
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

from softplc.errors import SoftPLCError
from softplc.plc import PLC

from . import drawing_table_pyrung
from .common import best_interleaved, loop, version_of
from .programs import (
    ROOT,
    chain_program,
    timer_counter_program,
    timer_counter_pyrung,
    to_pyrung,
)


def available() -> str | None:
    """None if pyrung imports, else the reason it does not."""
    try:
        import pyrung  # noqa: F401
    except Exception as e:  # any import failure makes the peer unavailable
        return f"{type(e).__name__}: {e}"
    return None


def _versus(plc: PLC, logic: Any, scans: int, repeat: int, warmup: int,
            setup: Any = None) -> tuple[float, float]:
    """(softplc, pyrung) seconds per scan, timed runs interleaved, same dt and scan count."""
    from pyrung import PLC as PyrungPLC

    with PyrungPLC(logic, dt=plc.scan_period) as py:
        if setup:
            setup(py)
        t = best_interleaved({"softplc": plc.scan, "pyrung": loop(py.step)}, scans, repeat,
                             warmup)
    return t["softplc"], t["pyrung"]


def crosscheck_chain(il: str, trials: int = 3) -> bool:
    """Random %M0-%M199, one scan on each side: every %M200-%M255 output agrees."""
    from pyrung import PLC as PyrungPLC

    logic, tags = to_pyrung(il)
    plc = PLC.from_source(il)
    rnd = random.Random(5)
    ok = True
    with PyrungPLC(logic, dt=0.01) as py:
        for _ in range(trials):
            for i, tag in tags.items():
                if i < 200:
                    v = rnd.random() < 0.5
                    tag.value = v
                    plc.mem.m[i] = bool(v)
            plc.scan()
            py.step()
            ok &= all(bool(plc.mem.m[i]) == bool(tag.value) for i, tag in tags.items()
                      if i >= 200)
    return ok


def run(scans: int = 200, repeat: int = 3, warmup: int = 20,
        drawing_table: Path | None = ROOT / "ladder_programs" / "drawing_table.il"
        ) -> dict[str, Any]:
    """{case: {softplc_us, pyrung_us, ratio, ...}} for the chain and timer/counter programs."""
    reason = available()
    if reason:
        return {"unavailable": reason}
    out: dict[str, Any] = {"version": version_of("pyrung"), "scans": scans, "repeat": repeat,
                           "warmup": warmup}
    # 250 rungs of Q := A AND (B OR C), inputs with a fixed random pattern
    il = chain_program(250)
    logic, tags = to_pyrung(il)
    rnd = random.Random(6)
    pattern = {i: rnd.random() < 0.5 for i in tags if i < 200}
    plc = PLC.from_source(il)
    for i, v in pattern.items():
        plc.mem.m[i] = bool(v)

    def set_inputs(py: Any) -> None:
        for i, v in pattern.items():
            tags[i].value = v

    t_soft, t_py = _versus(plc, logic, scans, repeat, warmup, set_inputs)
    out["chain250"] = _row("250 rungs A AND (B OR C) -> Q", plc, t_soft, t_py,
                           same=crosscheck_chain(il))
    # 50 timers + 50 counters
    text, cfg = timer_counter_program(50)
    plc = PLC.from_source(text, cfg)
    logic, _ = timer_counter_pyrung(50)
    t_soft, t_py = _versus(plc, logic, scans, repeat, warmup)
    out["timers_counters"] = _row("50 TON timers + 50 up-counters", plc, t_soft, t_py,
                                  same=None)
    out["drawing_table"] = _drawing_table(drawing_table, scans, repeat, warmup)
    return out


def _drawing_table(il: Path | None, scans: int, repeat: int, warmup: int) -> dict[str, Any]:
    """The drawing-table logic (no simulated devices on either side), moving a segment."""
    label = "drawing_table.il logic (Bresenham moving)"
    cfg = il.with_suffix(".toml") if il else None
    if il is None or not il.exists():
        return {"label": label, "error": f"{il} not found"}
    try:
        plc = PLC.from_file(il, cfg, devices=False)
    except SoftPLCError as e:
        return {"label": label, "error": f"softplc cannot load it yet: {e}"}
    dt = drawing_table_pyrung
    dt.apply_stimulus_softplc(plc)
    logic, tags = dt.build()
    t_soft, t_py = _versus(plc, logic, scans, repeat, warmup,
                           lambda py: dt.apply_stimulus_pyrung(tags))
    diff = dt.crosscheck(str(il), str(cfg))
    row = _row(label, plc, t_soft, t_py, same=not diff)
    if diff:
        row["differs"] = diff
    return row


def _row(label: str, plc: PLC, t_soft: float, t_py: float, same: bool | None) -> dict:
    return {"label": label, "instructions": plc.program.instruction_count,
            "rungs": len(plc.rungs), "softplc_us": t_soft * 1e6, "pyrung_us": t_py * 1e6,
            "ratio": t_py / t_soft, "outputs_agree": same}
