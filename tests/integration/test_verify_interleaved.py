"""The order of the engines (`engines._verify`): the base case (BMC at scan d) and the
induction step (k-induction at k = d) advance in turn, one depth each. Checked by the
progress they report, never by time: a counterexample of d scans is reported before the
induction tried any k past d; a proof at k once BMC is clean to k."""

from __future__ import annotations

from softplc.plc import PLC
from softplc.twido.address import Ref
from softplc.verify.checker import Checker
from softplc.verify.engines import FOUND, Result, verify
from softplc.verify.model import Model
from softplc.verify.replay import first_failure, replay
from softplc.verify.requirements import load_spec

SECONDS = 120  # per requirement: each answer below takes well under a second
PRESSES = "LDR %I0.0\n[ INC %MW0 ]\n"  # %MW0 counts rising edges of %I0.0
DELAYED = "LD %M0\nST %M1\nLD 0\nST %M0\n"  # %M1 is the last scan's %M0, cleared


def run(prog: str, check: str, depth: int, max_k: int, host: tuple[int, ...] = (),
        spacer: bool = False) -> tuple[Result, list[tuple[str, int]]]:
    """The result and the progress reported: (engine, depth) in order."""
    plc = PLC.from_source(prog, devices=False)
    spec = load_spec(None, [check], plc.profile)
    model = Model(plc, spec.reads, [Ref("MW", k) for k in host])
    seen: list[tuple[str, int]] = []
    res = verify(Checker(model, spec, spec.requirements[0]), depth, max_k, SECONDS,
                 ["%MF0"] if host else [], use_spacer=spacer,
                 progress=lambda engine, d, _s: seen.append((engine, d)))
    return res, seen


def turns(last: int) -> list[tuple[str, int]]:
    """BMC clean at scan d, then the induction step failing at k = d, for d <= last."""
    return [(engine, d) for d in range(1, last + 1) for engine in ("BMC", "k-induction")]


def test_a_one_scan_counterexample_comes_before_any_induction_step():
    """A host may write a NaN into %MF0 (`=` fails on it). Before, k-induction deepened
    to k = 8 for half the time (27 s) and only then BMC found this in 0.5 s."""
    res, seen = run("LD [ %MF0 > 0.0 ]\nST %Q0.0\n", "always %MF0 = %MF0", 2, 10,
                    host=(0, 1), spacer=True)
    assert res.status == "VIOLATED" and res.depth == 1, res
    assert seen == [(FOUND, 1)]
    assert res.trace[0]["values"] == {"%MF0": "nan"}


def test_a_deeper_counterexample_is_still_the_shortest_found_in_turn():
    """Three presses need five scans (press, release, press, release, press): BMC is clean
    to 4, the induction step tried up to k = 4 and no further; the counterexample replays
    and breaks the requirement at its last scan, not before."""
    res, seen = run(PRESSES, "always %MW0 < 3", 10, 10)
    assert res.status == "VIOLATED" and res.depth == 5, res
    assert seen == [*turns(4), (FOUND, 5)]
    assert replay(PLC.from_source(PRESSES, devices=False), res.trace) == []
    scans = [row["inputs"] for row in res.trace]
    assert first_failure(PLC.from_source(PRESSES, devices=False), "always %MW0 < 3",
                         scans) == 5


def test_a_proof_at_k_once_bmc_is_clean_to_k():
    """%M1 copies the %M0 of the scan before, then %M0 is cleared: from any state the
    first scan may set %M1, the second never (2-inductive). Proven as soon as the step
    holds at k = 2, BMC being clean to 2: no deeper BMC scan."""
    res, seen = run(DELAYED, "never %M1", 10, 10)
    assert (res.status, res.method, res.depth) == ("PROVEN", "k-induction (k=2)", 2), res
    assert seen == [*turns(1), ("BMC", 2)]


def test_a_proof_past_the_depth_takes_bmc_on_to_k():
    """--depth 1 bounds the counterexample search, not the base case of a proof: the
    induction step holds at k = 2, BMC is taken on to scan 2 (as before the interleaving)."""
    res, seen = run(DELAYED, "never %M1", 1, 10)
    assert (res.status, res.method, res.depth) == ("PROVEN", "k-induction (k=2)", 2), res
    assert seen == [*turns(1), ("BMC", 2)]


def test_each_engine_goes_on_alone_when_the_other_is_done():
    """%MW0 may reach 3 only after five scans: with max_k 2 BMC goes on alone to its
    depth 4 (UNKNOWN, clean to 4); with depth 2 the induction goes on alone to its max_k."""
    res, seen = run(PRESSES, "always %MW0 < 3", 4, 2)
    assert (res.status, res.depth) == ("UNKNOWN", 4), res
    assert seen == [*turns(2), ("BMC", 3), ("BMC", 4)]
    res, seen = run(PRESSES, "always %MW0 < 3", 2, 4)
    assert (res.status, res.depth) == ("UNKNOWN", 2), res
    assert seen == [*turns(2), ("k-induction", 3), ("k-induction", 4)]


def test_spacer_is_waited_for_once_both_engines_are_done():
    """Clean to 2 scans, no k up to 2: Spacer (started after 1-induction failed) is the
    last word; it finds the requirement fails later (the five scans), which BMC did not
    reach: UNKNOWN saying so, never a VIOLATED without a trace."""
    res, seen = run(PRESSES, "always %MW0 < 3", 2, 2, spacer=True)
    assert (res.status, res.method, res.depth) == (
        "UNKNOWN", "Spacer: fails after more scans than searched", 2), res
    assert seen[:4] == turns(2)
