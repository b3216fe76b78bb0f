"""Which program a restart runs (softplc.online.choose_program), in one process: the
command line's, the one kept with the state's data, or none until the operator chooses."""

from __future__ import annotations

import pytest

from softplc import online
from softplc.persist.kept import ProgramKeeper
from softplc.persist.retain import StateFileError, application_id
from softplc.plc import PLC

P = "LD 1\n[ %MW10 := 1 ]\n"
NEW = "LD 1\n[ %MW10 := 2 ]\n"
CONFIG = {"timers": {"%TM0": {"preset": 5}}, "modbus": {"port": 5021}}
SLOW = CONFIG | {"scan_period": "20ms"}


def app(text: str, config: dict = CONFIG) -> bytes:
    return application_id(text.encode(), config)


def plc(text: str = P, config: dict = CONFIG) -> PLC:
    return PLC.from_source(text, config, file="P.il")


def keeper_after_a_change(tmp_path) -> ProgramKeeper:
    """The keeper of a daemon started on P that loaded NEW online."""
    running = plc()
    keeper = ProgramKeeper(tmp_path / "S")
    keeper.running = online.kept_record(running, app(P), app(P))
    change = online.plan(running, NEW, None, file="NEW.il")
    keeper.keep(online.kept_record(running, app(NEW), app(P), change, "NEW.il", NEW))
    return ProgramKeeper(tmp_path / "S")  # as a restart reads it


def choose(p: PLC, keeper: ProgramKeeper, tmp_path, cmd: bytes = app(P), **kw):
    kw = {"keep_state": False, "from_state": False} | kw
    return online.choose_program(p, app(NEW), cmd, keeper, state=tmp_path / "S", **kw)


def test_the_original_command_line_runs_the_kept_program(tmp_path):
    p = plc()
    chosen, why = choose(p, keeper_after_a_change(tmp_path), tmp_path)
    assert chosen == app(NEW) and "NEW.il (online change 1" in why
    assert p.ast.source == NEW and p.ast.file == "NEW.il" and p.program_version == 1
    p.scan()
    assert p["%MW10"] == 2 and p.settings.modbus.port == 5021


def test_keep_state_runs_the_file_and_a_differing_file_stops(tmp_path):
    keeper = keeper_after_a_change(tmp_path)
    p = plc()
    assert choose(p, keeper, tmp_path, keep_state=True)[0] == app(P)
    assert p.ast.source == P
    other = plc("LD 1\n[ %MW10 := 3 ]\n")
    with pytest.raises(StateFileError) as e:
        choose(other, keeper, tmp_path, cmd=app("LD 1\n[ %MW10 := 3 ]\n"))
    assert "differs in the program text (from line 2" in str(e.value)
    assert other.ast.source.endswith("3 ]\n") and other.program_version == 0  # untouched
    slow = plc(P, SLOW)
    with pytest.raises(StateFileError, match=r"differs in .*configuration \(scan_period\)"):
        choose(slow, keeper, tmp_path, cmd=app(P, SLOW))
    with pytest.raises(StateFileError, match="cannot run with this command line's config"):
        choose(slow, keeper, tmp_path, cmd=app(P, SLOW), from_state=True)


def test_program_from_state_without_a_kept_program_is_refused(tmp_path):
    with pytest.raises(StateFileError, match="no copy of the program"):
        choose(plc(), ProgramKeeper(tmp_path / "S"), tmp_path, from_state=True)
    with pytest.raises(StateFileError, match="no copy of it is kept") as e:
        choose(plc(), ProgramKeeper(tmp_path / "S"), tmp_path)
    assert "--program-from-state" not in str(e.value) and "--keep-state" in str(e.value)
