"""The model's own facts (`softplc/verify/stateinv.py`): a Grafcet's steps mutually
exclusive, a step's flags, words written only with constants, found from the scan,
checked (random engine runs, then Houdini) and assumed by the requirements; a fact a
program breaks is never stated."""

from __future__ import annotations

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.model import Model
from softplc.verify.stateinv import candidates, houdini, prove, sift

# a chart 0 -> 1 -> 2 -> 0, each transition clearing its step; %M0 set on entering 2
CHART = """=*= 0
LD %I0.0
# 1
-*- 1
LD %I0.1
# 2
-*- 2
LD %I0.2
# 0
=*= POST
LD %X2
S %M0
LD %X0
R %M0
LD %X1
[ %MW0 := 5 ]
LD %X2
[ %MW0 := 7 ]
LD %I0.3
[ %MW1 := %MW1 + 1 ]
LD %X1
ST %Q0.1
LD %X2
ST %Q0.2
"""
# the same chart, but step 0 may also go to 2 in the scan it goes to 1 (two transitions)
FORK = CHART.replace("# 1\n", "# 1\nLD %I0.4\n# 2\n")


def _facts(src: str) -> list[str]:
    with PLC.from_source(src, {}, devices=False) as plc:
        model = Model(plc)
        facts = candidates(model)
        return houdini(model, sift(model, facts))


def test_chart_steps_exclusive_and_its_flags():
    kept = _facts(CHART)
    assert {"%X1 -> NOT %X2", "%X0 -> NOT %X1", "%X0 -> NOT %X2", "%X2 -> %M0",
            "%X0 -> NOT %M0", "%MW0 in [0, 5, 7]", "%X2 -> %MW0 = 7"} <= set(kept)
    assert not any(k.startswith("%MW1 in") for k in kept)  # a count: no table of states


def test_steps_two_transitions_activate_together_not_stated():
    kept = _facts(FORK)
    assert "%X1 -> NOT %X2" not in kept and "%X2 -> NOT %X1" not in kept
    assert "%X0 -> NOT %M0" in kept  # what still holds is kept


def test_sift_drops_what_an_engine_run_breaks():
    with PLC.from_source(FORK, {}, devices=False) as plc:
        model = Model(plc)
        facts = candidates(model)
        kept = {f.text for f in sift(model, facts)}
    assert "%X1 -> NOT %X2" not in kept  # both active after a fork: seen in a run
    assert "%X0 -> NOT %M0" in kept


def test_facts_proven_once_make_the_requirement_one_inductive(capsys, tmp_path):
    with PLC.from_source(CHART, {}, devices=False) as plc:
        assert "%X1 -> NOT %X2" in {f.text for f in prove(Model(plc))}
    path = tmp_path / "chart.il"
    path.write_text(CHART)
    assert main(["verify", str(path), "--require-expr", "never %Q0.1 AND %Q0.2",
                 "--max-k", "1", "--no-spacer", "-q"]) == 0
    assert "PROVEN" in capsys.readouterr().out


def test_fork_requirement_violated_not_assumed(capsys, tmp_path):
    path = tmp_path / "fork.il"
    path.write_text(FORK)
    assert main(["verify", str(path), "--require-expr", "never %Q0.1 AND %Q0.2",
                 "--max-k", "1", "--no-spacer", "-q"]) != 0
    assert "VIOLATED" in capsys.readouterr().out


def test_a_host_coil_is_free_in_every_scan(tmp_path, capsys):
    """A handshake coil (a RESET the program consumes) declared `host`: free in every
    scan, so what it drives is seen; not declared, it stays 0 (the program's)."""
    path, req = tmp_path / "reset.il", tmp_path / "reset.req.toml"
    path.write_text("LD %M2\nST %Q0.0\nLD %M2\nR %M2\n")
    req.write_text('[environment]\nhost = ["%M2"]\n\n[[requirement]]\n'
                   'name = "never reset"\ncheck = "never %Q0.0"\n')
    assert main(["verify", str(path), "--require", str(req), "-q"]) != 0
    assert "VIOLATED" in capsys.readouterr().out
    assert main(["verify", str(path), "--require-expr", "never %Q0.0", "-q"]) == 0


def test_facts_kept_for_another_model_of_the_same_system(monkeypatch):
    """A second model of the same program and configuration gets the facts proven for the
    first without a proof; another configuration of the program is proven again; a proof
    the time cut short is not kept (a later one, with time, proves them)."""
    from softplc.verify import stateinv

    def fresh() -> Model:
        plc = PLC.from_source(CHART, {}, devices=False)
        plc.close()
        return Model(plc)
    first = prove(fresh())
    assert "%X1 -> NOT %X2" in {f.text for f in first}
    calls: list[int] = []
    real = stateinv._houdini
    monkeypatch.setattr(stateinv, "_houdini", lambda *a: calls.append(1) or real(*a))
    assert [f.text for f in prove(fresh())] == [f.text for f in first] and not calls
    with PLC.from_source(CHART, {"scan_period": "50ms"}, devices=False) as plc:
        other = prove(Model(plc, host=[plc.symbols.ref("%M0")]))  # %M0 free: not a flag
    assert calls == [1] and "%X2 -> %M0" not in {f.text for f in other}
    stateinv._proven.clear()
    assert prove(fresh(), seconds=0.0) == [] and calls == [1, 1]
    assert {f.text for f in prove(fresh())} == {f.text for f in first} and len(calls) == 3
