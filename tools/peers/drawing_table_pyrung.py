"""ladder_programs/drawing_table.il written in pyrung, rung for rung (29 IL rungs).

An IL rung whose outputs are interleaved with further conditions (MPS/MRD/MPP, `ST x`
then `AND y`) becomes several pyrung rungs with the accumulated condition, which is the
IL semantics as long as the condition's operands are not written in between (true here,
and checked by `crosscheck`). Constants %KW0 = 2777 and %KW1 = 3000 come from
drawing_table.toml. Stimulus for both sides (`STIMULUS`): home switches closed, one long
segment requested, so the Bresenham motion runs during the whole measurement.

Timers: pyrung's on_delay counts the scan that enables it, Twido's TON does not, so the
presets are 3 and 2 ms here for the IL's 2 and 1 ms: both give the same PULSOS train (one
pulse every 5 scans of 1 ms, the same scans), which `crosscheck` confirms.
"""

from __future__ import annotations

from typing import Any

KW0, KW1 = 2777, 3000
STIMULUS = {"%I0.12": 1, "%I0.13": 1, "%MW0": 2400, "%MW1": 1700, "%MW5": 1, "%MW3": 120}
COMPARED = ["%MW32", "%MW36", "%MW33", "%MW37", "%MW67", "%MW10", "%M28", "%M27", "%M34",
            "%Q0.14"] + [f"%Q1.{k}" for k in range(8)]


def build() -> tuple[Any, dict[str, Any]]:
    """(pyrung Program, {IL address: tag})."""
    from pyrung import (
        Bool,
        Int,
        Or,
        Program,
        Timer,
        branch,
        calc,
        copy,
        latch,
        on_delay,
        out,
        reset,
        rung,
        system,
    )

    t: dict[str, Any] = {}
    for a in ("%M20", "%M25", "%M26", "%M27", "%M28", "%M32", "%M33", "%M34", "%M35", "%M36",
              "%I0.12", "%I0.13", "%I0.14", "%I0.15", "%Q0.14"):
        t[a] = Bool(a.strip("%").replace(".", "_"))
    for k in range(8):
        t[f"%Q1.{k}"] = Bool(f"Q1_{k}")
    for w in (0, 1, 3, 5, 10, 11, 31, 32, 33, 35, 36, 37, 38, 39, 62, 63, 64, 65, 66, 67, 68,
              69):
        t[f"%MW{w}"] = Int(f"MW{w}")
    tm = Timer.clone("TM", count=2)
    g = t.get
    M = {n: g(f"%M{n}") for n in (20, 25, 26, 27, 28, 32, 33, 34, 35, 36)}
    W = {n: g(f"%MW{n}") for n in (0, 1, 3, 5, 10, 11, 31, 32, 33, 35, 36, 37, 38, 39, 62, 63,
                                   64, 65, 66, 67, 68, 69)}
    tm0, tm1 = tm[1], tm[2]
    with Program(strict=False) as logic:
        with rung(tm1.Done):  # PULSOS
            out(M[20])
        with rung(~tm1.Done):
            on_delay(tm0, preset=3)
        with rung(tm0.Done):
            on_delay(tm1, preset=2)
        with rung(system.sys.first_scan):
            for n in (27, 25, 26, 35):
                latch(M[n])
            for x in (M[28], M[34], g("%Q0.14")):
                reset(x)
            copy(32000, W[32])
            copy(32000, W[36])
            for n in (35, 31, 38, 39, 69, 11):
                copy(0, W[n])
            copy(100, W[10])
        with rung(M[25], g("%I0.12")):
            calc(W[32] % 4, W[38])
            copy(0, W[32])
            reset(M[25])
        with rung(M[26], g("%I0.13")):
            calc(W[36] % 4, W[39])
            copy(0, W[36])
            reset(M[26])
        with rung(M[27], W[69] > KW1):
            reset(M[25])
            reset(M[26])
            reset(M[27])
            latch(M[34])
            copy(1, W[11])
        with rung(M[27], ~M[25], ~M[26]):
            reset(M[27])
            copy(0, W[10])
        with rung(M[20], ~M[35]):
            with branch(M[27]):
                calc(W[69] + 1, W[69])
            with branch(M[25]):
                calc(W[32] - 1, W[32])
            with branch(M[26]):
                calc(W[36] - 1, W[36])
        with rung(W[3] > 100, ~M[27], ~M[28], ~M[34]):
            out(M[32])
        with rung(M[32]):
            copy(W[0], W[35])
            copy(W[1], W[31])
            copy(0, W[3])
            copy(100, W[10])
            latch(M[28])
        with rung(M[32], W[35] < 0):
            copy(0, W[35])
        with rung(M[32], W[35] > KW0):
            copy(KW0, W[35])
        with rung(M[32], W[31] < 0):
            copy(0, W[31])
        with rung(M[32], W[31] > KW0):
            copy(KW0, W[31])
        with rung(M[32], W[5] != 0):
            latch(g("%Q0.14"))
        with rung(M[32], W[5] == 0):
            reset(g("%Q0.14"))
        with rung(M[32]):
            calc(W[35] - W[32], W[62])
            calc(W[31] - W[36], W[63])
            copy(1, W[65])
            copy(1, W[66])
        with rung(M[32], W[62] < 0):
            calc(0 - W[62], W[62])
            copy(-1, W[65])
        with rung(M[32], W[63] < 0):
            calc(0 - W[63], W[63])
            copy(-1, W[66])
        with rung(M[32]):
            calc(W[62] - W[63], W[67])
            calc(0 - W[63], W[64])
        with rung(W[32] == W[35], W[36] == W[31]):
            out(M[33])
        with rung(M[33], M[28]):
            reset(M[28])
            copy(0, W[10])
        with rung(Or(g("%I0.14"), g("%I0.15")), M[28]):
            reset(M[28])
            latch(M[34])
            copy(2, W[11])
        with rung(M[20], M[28]):
            out(M[36])
        with rung(M[36]):
            calc(W[67] + W[67], W[68])
        with rung(M[36], W[68] >= W[64]):
            calc(W[67] - W[63], W[67])
            calc(W[32] + W[65], W[32])
        with rung(M[36], W[68] <= W[62]):
            calc(W[67] + W[62], W[67])
            calc(W[36] + W[66], W[36])
        with rung(system.sys.always_on):
            calc(W[32] + W[38], W[33])
            calc(W[33] % 4, W[33])
            calc(W[36] + W[39], W[37])
            calc(W[37] % 4, W[37])
        for axis, w in ((0, 33), (1, 37)):
            for k in range(4):
                q = g(f"%Q1.{4 * axis + k}")
                if k < 2:
                    with rung(Or(W[w] == k, M[35])):
                        out(q)
                else:
                    with rung(W[w] == k):
                        out(q)
        with rung(M[20]):
            reset(M[35])
    return logic, t


def crosscheck(il: str, config: str, scans: int = 600) -> list[str]:
    """Run both sides `scans` scans of 1 ms from the stimulus; the addresses that differ
    at any of a few checkpoints (empty: the same behaviour)."""
    from pyrung import PLC as PyrungPLC

    from softplc.plc import PLC

    plc = PLC.from_file(il, config, devices=False)
    apply_stimulus_softplc(plc)
    logic, tags = build()
    bad: set[str] = set()
    with PyrungPLC(logic, dt=plc.scan_period) as py:
        apply_stimulus_pyrung(tags)
        for k in range(scans):
            plc.scan()
            py.step()
            if k % 50 == 0 or k == scans - 1:
                bad |= {a for a in COMPARED if int(plc[a]) != int(tags[a].value)}
    return sorted(bad)


def apply_stimulus_softplc(plc: Any) -> None:
    for a, v in STIMULUS.items():
        plc[a] = v


def apply_stimulus_pyrung(tags: dict[str, Any]) -> None:
    for a, v in STIMULUS.items():
        tags[a].value = bool(v) if a.startswith("%I") else v
