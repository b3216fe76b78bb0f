"""Debugger commands: execution (scan, step, stepi, run, continue, back)."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import TYPE_CHECKING

from softplc.config import duration
from softplc.debug.registry import command
from softplc.debug.report import position_text, run_text
from softplc.debug.stepper import STOPS_A_COMMAND, DebugError, Ran
from softplc.errors import ConfigError

if TYPE_CHECKING:
    from softplc.debug.session import Session


@command("scan")
def cmd_scan(s: Session, arg: str) -> str:
    """scan [N]: finish the scan in progress, then run N more scans (default 1; 0 when a
    scan is in progress). Stops at breakpoints."""
    n = s.count(arg, 0 if s.ctl.in_scan else 1)
    return run_text(s.ctl.run_scans(n), s.plc.ast)


def _repeat(s: Session, arg: str, step: Callable[[], Ran]) -> str:
    """`step` N times (default 1), or until a breakpoint, a fault or the end stops it."""
    ran: Ran | None = None
    for _ in range(s.count(arg, 1)):
        ran = step()
        if ran.reason in STOPS_A_COMMAND:
            break
    return run_text(ran, s.plc.ast) if ran is not None else ""


@command("step", "s")
def cmd_step(s: Session, arg: str) -> str:
    """step [N]: run to the start of the next rung (entering a scan if at the boundary)."""
    return _repeat(s, arg, s.ctl.step)


@command("stepi", "si")
def cmd_stepi(s: Session, arg: str) -> str:
    """stepi [N]: run one instruction (entering a scan if at the boundary)."""
    return _repeat(s, arg, s.ctl.step_instruction)


@command("run", "r")
def cmd_run(s: Session, arg: str) -> str:
    """run N | run Ts: run N scans (run 100) or T seconds of PLC time (run 2s, run 500ms).
    Stops at breakpoints."""
    a = arg.strip()
    if not a:
        raise DebugError("run N (scans) or run T (seconds, e.g. 2s, 500ms)")
    if re.fullmatch(r"\d+", a):
        n = int(a)
    else:
        try:
            secs = duration(a, "run")
        except ConfigError as e:
            raise DebugError(str(e)) from None
        n = max(1, round(secs / s.plc.scan_period))
    if s.ctl.in_scan:
        n = max(0, n - 1)  # the scan in progress counts as one
    return run_text(s.ctl.run_scans(n), s.plc.ast)


@command("continue", "c", "cont")
def cmd_continue(s: Session, arg: str) -> str:
    """continue: run until a breakpoint or watch stops it (at most 100000 scans;
    Ctrl-C or a fault stops it)."""
    if not s.ctl.breaks or not any(b.enabled for b in s.ctl.breaks):
        raise DebugError("no breakpoint is enabled: continue would never stop "
                         "(use 'run N' or set one with 'break')")
    return run_text(s.ctl.run_until_hit(s.continue_limit), s.plc.ast, s.continue_limit)


@command("back")
def cmd_back(s: Session, arg: str) -> str:
    """back [N]: go back N scans (default 1; a scan in progress counts as one)."""
    n = s.count(arg, 1)
    if n:
        s.ctl.back(n)
    return position_text(s.ctl.position(), s.plc.ast)
