"""Deep timer windows (issue 34 item 4): a two-hand control whose proof needs the relation
between three timers (a 0.5 s window at a 50 ms scan: k = 11 without it) is PROVEN, its
response requirement for every scan; the time goes in tools/bench_verify.py."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import z3
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softplc.blocks.timer import time_unit, timer_cap
from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.checker import Checker, _reads
from softplc.verify.clock import Clock
from softplc.verify.engines import verify
from softplc.verify.lemmas import houdini
from softplc.verify.model import Model, sort_of
from softplc.verify.replay import set_inputs
from softplc.verify.requirements import load_spec

LP = Path(__file__).resolve().parents[2] / "ladder_programs"
MAX_K = 3  # the window (11 scans) is not what proves it: the timers' relations are


def test_two_hand_control_proven_with_a_small_k(capsys):
    args = ["verify", str(LP / "two_hand.il"), "--config", str(LP / "two_hand.toml"),
            "--require", str(LP / "two_hand.req.toml"), "--max-k", str(MAX_K), "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("PROVEN") == 3
    assert "for every scan: k-induction" in out


def test_timers_sharing_the_first_hand_are_related():
    """The window timer's input is on whenever a hand's is, and it started no later."""
    with PLC.from_file(LP / "two_hand.il", LP / "two_hand.toml", devices=False) as plc:
        spec = load_spec(LP / "two_hand.req.toml", [], plc.profile)
        model = Model(plc, spec.reads, spec.host, spec.periods)
        ck = Checker(model, spec, spec.requirements[1], [])
        kept = houdini(ck, Clock(60))
        st = {k: z3.Const(k, sort_of(s)) for k, s in ck.state_keys().items()}
        texts = [str(ck.candidates(st)[i]) for i in kept]
    assert any("%TM0._in" in t and "%TM2._in" in t and "ULE" in t for t in texts)
    assert any("%TM1._in" in t and "%TM2._in" in t and "ULE" in t for t in texts)


def test_counter_done_bit_against_its_value(capsys):
    """A counter jumped over in some scans keeps its done bit as state: D = (V = P) is
    kept, and the requirement reading it is proven."""
    src = ("LD %I0.2\nJMPC %L1\nBLK %C0\nLD %I0.0\nCU\nLD %I0.1\nCD\nEND_BLK\n"
           "%L1:\nLD %C0.D\nST %Q0.1\n")
    with PLC.from_source(src, {"counters": {"%C0": {"preset": 5}}}, devices=False) as plc:
        spec = load_spec(None, ["%Q0.1 -> %C0.V = 5"], plc.profile)
        ck = Checker(Model(plc, spec.reads), spec, spec.requirements[0])
        st = {k: z3.Const(k, sort_of(s)) for k, s in ck.state_keys().items()}
        texts = [str(ck.candidates(st)[i]) for i in houdini(ck, Clock(60))]
    assert "%C0.D == (%C0.V == %C0.P)" in texts


# ---- off-delay and pulse timers, counters against their preset ---------------------------
BLOCKS = {"timers": {"%TM0": {"type": "TOF", "base": "100ms", "preset": 30},
                     "%TM1": {"type": "TP", "base": "100ms", "preset": 30},
                     "%TM2": {"type": "TON", "base": "100ms", "preset": 20}},
          "counters": {"%C0": {"preset": 5}}}
TOF = "BLK %TM0\nLD %I0.0\nIN\nOUT_BLK\nLD Q\nST %Q0.0\nEND_BLK\n"
TP = "BLK %TM1\nLD %I0.1\nIN\nOUT_BLK\nLD Q\nST %Q0.1\nEND_BLK\n"
SMALL_K = 3  # without the candidates these need a k the stuttering never allows


@pytest.mark.parametrize("prog, check", [
    (TOF, "%TM0.V > 0 AND %TM0.V < 30 -> %Q0.0"),  # counting after IN fell: Q still on
    (TP, "%TM1.V > 0 -> %Q0.1 OR %I0.1"),  # V runs only in the pulse or while IN holds it
    ("LD %I0.0\nCU %C0\nLD %C0.D\nR %C0\n", "never %C0.V > 7"),  # reset at its preset
])
def test_off_delay_pulse_and_counter_invariants_prove_at_k1(prog, check):
    """Each was UNKNOWN with k-induction up to k = 3 (a state the stuttering scans never
    leave: V halfway and Q off, a count of 6): the invariants make it 1-inductive."""
    with PLC.from_source(prog, BLOCKS, devices=False) as plc:
        spec = load_spec(None, [check], plc.profile)
        ck = Checker(Model(plc, spec.reads), spec, spec.requirements[0])
        res = verify(ck, SMALL_K, SMALL_K, 60, [], use_spacer=False)
    assert (res.status, res.method) == ("PROVEN", "k-induction (k=1)"), res


# random programs of TOF / TP / TON timers and a counter, some blocks jumped over
LOADS = ["LD %I0.0", "LD %I0.1", "LDN %I0.0", "LD %M0", "LD %C0.D", "LD %TM0.Q"]


def block_rungs(draw: st.DrawFn) -> str:
    lines: list[str] = []
    for label in range(1, draw(st.integers(2, 6))):
        kind = draw(st.sampled_from(["timer", "count", "jump", "bit"]))
        load = draw(st.sampled_from(LOADS))
        if kind == "timer":
            n = draw(st.integers(0, 2))
            lines += [f"BLK %TM{n}", load, "IN", "OUT_BLK", "LD Q", "ST %M1", "END_BLK"]
        elif kind == "count":
            lines += [load, f"{draw(st.sampled_from(['CU', 'CD', 'R', 'S']))} %C0"]
        elif kind == "jump":
            lines += ["LD %I0.2", f"JMPC %L{label}", "BLK %TM0", load, "IN", "END_BLK",
                      "LD %I0.1", "CU %C0", f"%L{label}:"]
        else:
            lines += [load, "ST %M0"]
    return "\n".join(lines) + "\n"


def engine_state(plc: PLC, ck: Checker) -> dict[str, Any]:
    """The engine's state as the model's keys: fields, a timer's last IN, `_on`, its
    elapsed time since it started (in the model's units, saturated as the model does)."""
    scan = ck.model.scan_info()
    out = {}
    for key, sort in ck.state_keys().items():
        m = re.fullmatch(r"%(TM|C)(\d+)\.(\w+)", key)
        blk = plc.mem.blocks[m[1]][int(m[2])] if m else None
        f = m[3] if m else ""
        if blk is not None and f == "_el":
            el = (plc.engine.clock.now_us - blk._t0) // time_unit(blk, ck.model.period_us)
            v: Any = min(el, timer_cap(blk, scan))
        elif blk is not None and f.startswith("_"):
            v = getattr(blk, f)
        elif key.startswith("%"):
            v = plc[key]
        else:
            continue  # none of the candidates reads it
        out[key] = z3.BoolVal(bool(v)) if sort == "bool" else z3.BitVecVal(
            int(v), sort_of(sort).size())
    return out


@settings(max_examples=examples(40), deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), scans=st.lists(st.fixed_dictionaries(
    {"%I0.0": st.integers(0, 1), "%I0.1": st.integers(0, 1), "%I0.2": st.integers(0, 1)}),
    min_size=1, max_size=40))
def test_kept_invariants_hold_on_engine_runs(data, scans):
    """Soundness: what Houdini keeps of the candidates (timers of every type, counters)
    holds in the engine's state after every scan of random runs."""
    src = block_rungs(data.draw)
    with PLC.from_source(src, BLOCKS, devices=False) as plc:
        spec = load_spec(None, ["always %TM0.V >= 0 AND %TM1.V >= 0 AND %TM2.V >= 0 AND "
                                "%C0.V >= 0 AND (%TM0.Q OR %TM1.Q OR %TM2.Q OR %C0.D OR %M1 "
                                "OR NOT %M0)"], plc.profile)
        ck = Checker(Model(plc, spec.reads), spec, spec.requirements[0])
        kept = houdini(ck, Clock(60))
        names = {f"{k}@s": k for k in ck.state_keys()}
        st_vars = {k: z3.Const(f"{k}@s", sort_of(s)) for k, s in ck.state_keys().items()}
        cands = ck.candidates(st_vars)  # once: the same terms for every index kept
        terms = [cands[i] for i in kept]
        with PLC.from_source(src, BLOCKS, devices=False) as eng:
            for n, inputs in enumerate(scans, 1):
                set_inputs(eng, inputs)
                eng.scan()
                now = engine_state(eng, ck)
                for t in terms:
                    pairs = [(st_vars[k], now[k]) for k in _reads(t, names)]
                    assert z3.is_true(z3.simplify(z3.substitute(t, *pairs))), \
                        f"scan {n}: {t}\n{src}"
