"""Deep timer windows (issue 34 item 4): a two-hand control whose proof needs the relation
between three timers (a 0.5 s window at a 50 ms scan: k = 11 without it) is PROVEN, its
response requirement for every scan; the time goes in tools/bench_verify.py."""

from __future__ import annotations

from pathlib import Path

import z3

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.checker import Checker
from softplc.verify.clock import Clock
from softplc.verify.lemmas import houdini
from softplc.verify.model import Model, sort_of
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
