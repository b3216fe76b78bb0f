"""The Remote Link's objects in the tools (issue 35): `softplc check`, the debugger's `link`
command, `softplc verify` (the link words free inputs of the model)."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.cli import main
from softplc.debug.session import Session
from softplc.plc import PLC
from softplc.runtime.remotelink import InMemoryTransport
from softplc.verify.checker import Checker
from softplc.verify.engines import verify
from softplc.verify.model import Model
from softplc.verify.requirements import load_spec
from softplc.verify.system import free_objects

MASTER = {"remote_link": {"address": 0, "remotes": {"1": "peer"}}}
PROGRAM = "LD [ %INW1.0 > 100 ]\nST %Q0.0\n[ %QNW1.0 := %MW0 ]\n"


def checker(text: str, check: str, config: dict) -> Checker:
    plc = PLC.from_source(text, config, devices=False)
    spec = load_spec(None, [check], plc.profile)
    return Checker(Model(plc, spec.reads, spec.host, None), spec, spec.requirements[0])


def test_check_accepts_link_words_and_names_a_wrong_station(tmp_path: Path, capsys) -> None:
    prog, cfg = tmp_path / "m.il", tmp_path / "m.toml"
    cfg.write_text('[remote_link]\naddress = 0\nremotes = { 1 = "peer" }\n')
    prog.write_text(PROGRAM)
    assert main(["check", str(prog), "--config", str(cfg)]) == 0
    prog.write_text(PROGRAM + "[ %QNW4.0 := 1 ]\n")
    assert main(["check", str(prog), "--config", str(cfg)]) == 1
    err = capsys.readouterr()
    assert f"{prog}:4:3" in err.out + err.err and "station 4 is not a peer" in err.out + err.err


def test_debugger_link_command_shows_stations_and_words() -> None:
    plc = PLC.from_source(PROGRAM, MASTER)
    s = Session(plc, None)
    assert "station 1: ABSENT" in s.execute("link")
    peer = PLC.from_source("LD 1\n[ %QNW0.0 := 123 ]\n", {"remote_link": {"address": 1}})
    t = InMemoryTransport()
    plc.machine.link.transport = t
    t.attach(peer.machine.link)
    peer.scan()
    plc.machine.link.cycle()
    out = s.execute("link")
    assert "station 1: present" in out and "%SW111=16#0001" in out and "123" in out
    assert "not configured" in Session(PLC.from_source("LD 1\nST %Q0.0\n"), None).execute("link")


def test_verify_takes_link_words_and_status_as_free() -> None:
    res = verify(checker(PROGRAM, "never %Q0.0", MASTER), 8, 4, 20, [], use_spacer=True)
    # %MW0 is free too (a host may write it; issue 34: no vacuous proof by default)
    assert res.status == "VIOLATED" and res.trace[0]["inputs"]["%INW1.0"] == 101
    free = free_objects(PLC.from_source(PROGRAM, MASTER), False)
    assert "%SW111" in free and "%SW112" in free
    ok = "LD [ %INW1.0 > 100 ]\nANDN [ %INW1.0 > 50 ]\nST %Q0.0\n"
    assert verify(checker(ok, "never %Q0.0", MASTER), 8, 4, 20, [],
                  use_spacer=True).status == "PROVEN"


@pytest.mark.parametrize(("program", "config", "proven"), [
    ("station.il", "filler.toml", 2), ("station.il", "capper.toml", 2),
    ("master.il", "master.toml", 3)])
def test_the_example_plants_requirements_are_proven(program, config, proven, capsys) -> None:
    d = Path(__file__).resolve().parents[2] / "ladder_programs" / "plant"
    req = d / ("station.req.toml" if program == "station.il" else "master.req.toml")
    assert main(["verify", str(d / program), "--config", str(d / config),
                 "--require", str(req)]) == 0
    out = capsys.readouterr().out
    assert out.count("PROVEN") == proven and "%SW111 (the Remote Link" in out
