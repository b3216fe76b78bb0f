"""Debugger commands: breakpoints and watches (break, watch, breakpoints, delete, disable,
enable, history)."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from softplc.debug.registry import CMP_OPS, COND, command, parse_value
from softplc.debug.report import executed_text
from softplc.debug.stepper import BreakKind, Breakpoint, DebugError, resolve_rung
from softplc.twido.display import format_value

if TYPE_CHECKING:
    from softplc.debug.session import Session


@command("break", "b")
def cmd_break(s: Session, arg: str) -> str:
    """break RUNG | break %Li | break when COND: stop before a rung (number or title), at a
    label, or when a condition becomes true: `break when %MW32 = 100` (= <> < <= > >=, a
    value or an address on the right), `break when %M33 rises` (falls, changes).
    Without argument: list the breakpoints."""
    if not arg:
        return cmd_breakpoints(s, "")
    m = re.match(r"when\s+(.*)$", arg, re.I)
    if m:
        return _break_when(s, m[1])
    r = resolve_rung(s.plc.ast, arg, s.plc.symbols)
    b = s.ctl.breakpoints.add(kind=BreakKind.RUNG, text=r.name, rung=r.index, key=arg)
    return f"breakpoint #{b.id} at {r.name}"


def _break_when(s: Session, text: str) -> str:
    parts = text.split()
    if len(parts) == 2 and parts[1].lower() in ("rises", "falls", "changes"):
        refs = s.parse_obj(parts[0])
        if len(refs) != 1:
            raise DebugError("a condition names one object, not a range")
        ref = refs[0]
        b = s.ctl.breakpoints.add(kind=BreakKind.COND, text=f"{ref} {parts[1].lower()}",
                      test=lambda: s.read(ref), mode=parts[1].lower())
        return f"breakpoint #{b.id} when {b.text}"
    m = COND.match(text)
    if not m:
        raise DebugError("condition: ADDR OP VALUE (e.g. %MW32 = 100) or ADDR rises / "
                         "falls / changes")
    left = s.parse_obj(m[1])
    if len(left) != 1:
        raise DebugError("a condition names one object, not a range")
    lref, op = left[0], CMP_OPS[m[2]]
    if m[3].startswith("%"):
        rref = s.parse_obj(m[3])[0]

        def right() -> Any:
            return s.read(rref)
    else:
        val = parse_value(m[3])

        def right() -> Any:
            return val
    b = s.ctl.breakpoints.add(kind=BreakKind.COND, text=f"{lref} {m[2]} {m[3]}",
                  test=lambda: bool(op(s.read(lref), right())))
    return f"breakpoint #{b.id} when {b.text}" + (" (true now: stops when it becomes "
                                                  "true again)" if b.last else "")


@command("watch")
def cmd_watch(s: Session, arg: str) -> str:
    """watch ADDR: stop when the object changes (a data breakpoint); its changes are
    kept for `history`."""
    refs = s.parse_obj(arg) if arg else []
    if len(refs) != 1:
        raise DebugError("watch one object, e.g. watch %MW32")
    ref = refs[0]
    b = s.ctl.breakpoints.add(kind=BreakKind.WATCH, text=s.title(ref),
                                test=lambda: s.read(ref))
    return f"watch #{b.id} {s.title(ref)} (now {s.fmt(ref, b.last)})"


_LISTED_AS = {BreakKind.RUNG: "at", BreakKind.COND: "when", BreakKind.WATCH: "watch"}


@command("breakpoints", "breaks", "tb")
def cmd_breakpoints(s: Session, arg: str) -> str:
    """breakpoints: list breakpoints and watches."""
    if not s.ctl.breaks:
        return "no breakpoints"
    lines = []
    for b in s.ctl.breaks:
        what = _LISTED_AS[b.kind]
        lines.append(f"#{b.id:<3} {what} {b.text}{'' if b.enabled else '  (disabled)'}"
                     f"  hits {b.hits}")
    return "\n".join(lines)


def _ids(s: Session, arg: str) -> list[Breakpoint]:
    if not arg or arg == "all":
        return s.ctl.breakpoints.find(None)
    ids = []
    for t in arg.replace(",", " ").split():
        try:
            ids.append(int(t.lstrip("#")))
        except ValueError:
            raise DebugError(f"{t!r} is not a breakpoint number") from None
    return s.ctl.breakpoints.find(ids)


@command("delete", "d")
def cmd_delete(s: Session, arg: str) -> str:
    """delete [ID...]: delete breakpoints/watches (all without argument)."""
    gone = _ids(s, arg)
    s.ctl.breakpoints.delete(gone)
    return f"deleted {len(gone)} breakpoint(s)"


@command("disable")
def cmd_disable(s: Session, arg: str) -> str:
    """disable [ID...]: disable breakpoints (all without argument)."""
    for b in _ids(s, arg):
        b.enabled = False
    return cmd_breakpoints(s, "")


@command("enable")
def cmd_enable(s: Session, arg: str) -> str:
    """enable [ID...]: enable breakpoints (all without argument)."""
    for b in _ids(s, arg):
        b.enabled = True
    return cmd_breakpoints(s, "")


@command("history")
def cmd_history(s: Session, arg: str) -> str:
    """history [ADDR]: the recorded changes of watched objects (watch them first)."""
    keys = [str(s.parse_obj(arg)[0])] if arg else list(s.ctl.changes)
    if not keys:
        return "nothing watched: 'watch ADDR' records the changes of an object"
    lines = []
    for key in keys:
        if key not in s.ctl.changes:
            raise DebugError(f"{key} is not watched: 'watch {key}' first")
        hist = s.ctl.changes[key]
        lines.append(f"{key}: {len(hist)} change(s)")
        for c in hist:
            lines.append(f"  scan {c.scan:>6}  t={c.time:9.3f} s  {executed_text(c.where):<18} "
                         f"{format_value(c.old)} -> {format_value(c.new)}")
    return "\n".join(lines)
