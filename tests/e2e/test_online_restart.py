"""Issue 31 item 2: what runs survives a restart. `softplc run P.il --state S`, `softplc
load NEW.il`, a host writes %MW11 = 777, kill -9, then the same command line again: NEW
runs, warm, with %MW11 = 777, and the banner says which program runs and why. A program
file that differs from the kept one stops the start with what differs and the choices,
leaving the state file as it was (softplc.persist.kept, softplc.online.choose_program)."""

from __future__ import annotations

from daemon_util import Daemon, started
from waits import WAIT_S, until

from softplc.cli import main as cli
from softplc.commands.io import Client

# %MW12 counts scans; %MW10 says which program runs; %MW11 no program writes (the host's)
P = "LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW10 := 1 ]\nEND\n"
NEW = "LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW10 := 2 ]\nEND\n"
OTHER = "LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW10 := 3 ]\nEND\n"


def words(d: Daemon, addr: int, n: int) -> list[int]:
    with d.client() as c:
        return c.read_registers(addr, n)


def runs(d: Daemon, which: int) -> None:
    """The program that writes `which` into %MW10 runs: %MW10 cleared by the host comes
    back as `which` (the retained value alone would not tell)."""
    with d.client() as c:
        c.write_registers(10, [0])
    until(lambda: words(d, 10, 1) == [which])


def test_an_online_change_and_its_data_survive_kill_9(daemons, tmp_path, capsys):
    prog, new = tmp_path / "P.il", tmp_path / "NEW.il"
    prog.write_text(P)
    new.write_text(NEW)
    args = ("--state", str(tmp_path / "S"), "--web", "0", "--stats-interval", "0")
    d = started(daemons, tmp_path, *args, program=prog)
    port = str(d.web_port())
    until(lambda: words(d, 10, 1) == [1])
    assert cli(["load", str(new), "--port", port]) == 0
    assert "version 1" in capsys.readouterr().out
    until(lambda: words(d, 10, 1) == [2])
    with d.client() as c:
        c.write_registers(11, [777])
    until(lambda: words(d, 11, 1) == [777])
    d.kill()  # SIGKILL: nothing saved at shutdown

    d = started(daemons, tmp_path, *args, program=prog)  # the original command line
    banner = "".join(d.out)
    assert "NEW.il (kept with the state)" in banner, banner
    assert "warm start (program kept in the state file: " in banner, banner
    assert "NEW.il (online change 1, loaded " in banner
    assert "the command line's program is the one it replaced" in banner
    assert words(d, 11, 1) == [777]  # with its data
    runs(d, 2)  # NEW runs
    info = Client("127.0.0.1", d.web_port()).request("program")
    assert info["source"] == NEW and info["info"]["version"] == 1
    assert info["info"]["file"].endswith("NEW.il")
    d.kill()

    # again: a second restart of the same command line is the same (nothing drifts)
    d = started(daemons, tmp_path, *args, program=prog)
    assert words(d, 11, 1) == [777]
    runs(d, 2)
    assert d.stop() == 0


def test_a_program_file_that_differs_stops_the_start_until_the_operator_chooses(
        daemons, tmp_path):
    prog = tmp_path / "P.il"
    prog.write_text(P)
    state = tmp_path / "S"
    args = ("--state", str(state), "--stats-interval", "0")
    d = started(daemons, tmp_path, *args, program=prog)
    with d.client() as c:
        c.write_registers(11, [777])
    until(lambda: words(d, 11, 1) == [777])
    assert d.stop() == 0
    before = state.read_bytes()

    prog.write_text(OTHER)  # the operator edits the file: not a silent cold start
    d = started(daemons, tmp_path, *args, program=prog, wait=False)
    assert d.proc.wait(WAIT_S) == 1
    err = d.stderr()
    assert "Traceback" not in err
    assert "P.il (started, loaded" in err, err
    assert "differs in the program text (from line 3" in err, err
    assert "Nothing was started; the state file is kept as it is" in err
    assert "--program-from-state" in err and "--keep-state" in err and "--cold" in err
    assert state.read_bytes() == before

    d = started(daemons, tmp_path, *args, "--program-from-state", program=prog)
    assert "program kept in the state file" in "".join(d.out)
    assert words(d, 11, 1) == [777]
    runs(d, 1)  # the kept P, not the file's OTHER
    assert d.stop() == 0

    d = started(daemons, tmp_path, *args, "--keep-state", program=prog)
    assert "data kept (--keep-state)" in "".join(d.out)
    assert words(d, 11, 1) == [777]
    runs(d, 3)  # the file's program, with the data
    assert d.stop() == 0
