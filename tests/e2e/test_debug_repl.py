"""The debugger as a person uses it: `python -m softplc repl` in a pseudo-terminal.

`test_small_program_session_and_ctrl_d` starts the real interpreter on a terminal of its
own (pexpect.spawn); the longer sessions run the same command line forked from the test
zygote (tests/zygote.py) on a pseudo-terminal: the same readline, completion, history and
end of input, without an interpreter's start and imports each (about 1 s of CPU)."""

from __future__ import annotations

import fcntl
import os
import pty
import signal
import struct
import sys
import termios
from pathlib import Path

import pexpect
import pytest
from pexpect.fdpexpect import fdspawn
from waits import WAIT_S
from zygote import forking, zygote

from softplc.cli import main

HERE = Path(__file__).parents[1]  # tests/
ROOT = HERE.parent
TABLE = ROOT / "ladder_programs" / "drawing_table.il"
PROMPT = r"\(softplc\) "


ROWS, COLS = 60, 200
EXPECT_S = 20
EOT = "\x04"  # Ctrl-D: the terminal's end of input (VEOF) [termios(3)]


class ForkedTerminal(fdspawn):
    """`python -m softplc ARGS` forked from the test zygote, its stdin, stdout and stderr a
    pseudo-terminal of ROWS x COLS: pexpect's interface as far as these tests use it."""

    def __init__(self, argv: list[str], env: dict[str, str]):
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
        self._zygote = zygote()
        try:
            self.pid = self._zygote.fork(argv, ROOT, env, [slave, slave, slave])
        finally:
            os.close(slave)  # the child's end: EOF (EIO) here once the child has exited
        super().__init__(master, encoding="utf-8", timeout=EXPECT_S)

    def sendeof(self) -> None:
        self.send(EOT)

    def close(self, force: bool = True) -> None:
        """As pexpect's: the child ends (killed unless its output has ended), reaped."""
        if self._zygote.wait(self.pid, WAIT_S if self.flag_eof else 0) is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:  # it ended, its exit not yet reported
                pass
            self._zygote.wait(self.pid, WAIT_S)
        if not self.closed:
            super().close()


def spawn(tmp_path: Path, *args: str, fork: bool = False) -> pexpect.spawn | ForkedTerminal:
    """The REPL on a terminal: a new interpreter, or (`fork`) forked from the zygote."""
    env = dict(os.environ, SOFTPLC_HISTORY=str(tmp_path / "hist"), TERM="dumb",
               PYTHONIOENCODING="utf-8")
    argv = ["repl", *args]
    if fork and forking():
        # written at once, as a terminal's line-buffered stdout is at each prompt
        child = ForkedTerminal(argv, dict(env, PYTHONUNBUFFERED="1"))
    else:
        child = pexpect.spawn(sys.executable, ["-m", "softplc", *argv], cwd=str(ROOT),
                              env=env, encoding="utf-8", timeout=EXPECT_S,
                              dimensions=(ROWS, COLS))
    child.expect(PROMPT)
    return child


def cmd(child: pexpect.spawn, line: str) -> str:
    child.sendline(line)
    child.expect(PROMPT)
    return child.before


@pytest.mark.skipif(not TABLE.exists(), reason="drawing table program not there")
def test_drawing_table_session_in_a_terminal(tmp_path: Path) -> None:
    child = spawn(tmp_path, str(TABLE.relative_to(ROOT)), "--config",
                  str(TABLE.with_suffix(".toml").relative_to(ROOT)), fork=True)
    try:  # drawing_table.toml names its objects: each shows its symbol (TRAYEX, PX)
        assert "breakpoint #1 at rung" in cmd(child, "break X home switch")
        out = cmd(child, "continue")
        assert "breakpoint #1" in out and "before rung 4" in out
        assert "before rung 5" in cmd(child, "step")
        assert "watch #2 %MW32 TRAYEX (now 32000)" in cmd(child, "watch %MW32")
        assert "%I0.12 PX forced to 1" in cmd(child, "force %I0.12 1")
        assert "breakpoint #1" in cmd(child, "continue")  # the next scan, rung 4 again
        assert "watch #2 %MW32 TRAYEX: 32000 -> 0 (in rung 4 instr 3)" in cmd(child, "step")
        screen = cmd(child, "rung 4")
        assert "%I0.12" in screen and "1F" in screen and "═" in screen
        assert "[scan 1," in cmd(child, "back")
        assert "%MW32 TRAYEX = 32000" in cmd(child, "print %MW32")
        assert "%I0.12 PX = 1  [forced]" in cmd(child, "print %I0.12")
        # tab completes a command name, then an address
        child.send("prin\t%TM1.\t")
        child.sendline("")
        child.expect(PROMPT)
        assert "%TM1.Q OSC_OFF.Q = " in child.before
        assert "error: malformed address" in cmd(child, "print %ZZ")  # still alive
        child.sendline("quit")
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
    assert "print %MW32" in (tmp_path / "hist").read_text()  # readline history saved


def test_small_program_session_and_ctrl_d(tmp_path: Path) -> None:
    child = spawn(tmp_path, "tests/debug_sample.il", "--config", "tests/debug_sample.toml")
    try:
        assert "queued" in cmd(child, "set %I0.0 1")
        assert "[scan 3, t = 0.030 s]" in cmd(child, "run 3")
        assert "%MW0 = 1" in cmd(child, "print %MW0")
        assert "rung 2  branches" in cmd(child, "rung 2")
        assert "unknown command" in cmd(child, "frobnicate")
        child.sendeof()
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)


def test_batch_commands(capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["repl", str(HERE / "debug_sample.il"), "--config", str(HERE / "debug_sample.toml"),
               "-x", "set %MW0 5", "-x", "scan",
               "-x", "print/x %MW0", "-x", "quit"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "(softplc) print/x %MW0\n%MW0 = 16#0005" in out and out.rstrip().endswith("bye")


PLANT = ROOT / "ladder_programs" / "plant" / "plant.toml"


def test_plant_session_in_a_terminal(tmp_path: Path) -> None:
    """`softplc repl plant.toml`: a breakpoint in a peer stops the whole line; `back`
    rewinds every controller and the belt; Ctrl-D leaves."""
    child = spawn(tmp_path, str(PLANT.relative_to(ROOT)), fork=True)
    try:
        assert "focus: master" in child.before  # the intro
        assert "queued" in cmd(child, "set master:%I0.0 1")
        assert "breakpoint #1 when %Q0.0 rises" in cmd(child, "break when capper:%Q0.0 rises")
        out = cmd(child, "continue")
        assert "[capper] breakpoint #1 when %Q0.0 rises" in out and "] capper: [scan" in out
        assert "%Q0.0 TOOL = 1" in cmd(child, "print %Q0.0")  # the capper's, now focused
        assert "still to scan" not in cmd(child, "scan 0")  # the instant finished
        cmd(child, "delete")
        before = cmd(child, "plant")
        assert "belt         boxes=2 fed=2 delivered=0" in before
        assert "[plant t = 6.150 s, instant 616]" in cmd(child, "run 1s")  # 100 of 10 ms
        assert cmd(child, "plant") != before
        assert "instant 516]" in cmd(child, "back 100")
        assert cmd(child, "plant") == before  # every controller, the belt
        child.sendeof()
        child.expect(pexpect.EOF)
    finally:
        child.close(force=True)
