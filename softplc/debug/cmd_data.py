"""Debugger commands: data (print, set, force, unforce, trace).

They go through the access port (`softplc.access`), as the web monitor does: its typed
reads, its value and writability checks, its force and unforce commands. The debugger owns
the scan thread, so the port has no scan hooks here: a force or unforce is applied at once
(`apply_now`), a set waits in the debugger's own queue for the next scan (its history
keeps it: `back` takes it back with the scan).
"""

from __future__ import annotations

import csv
import re
from typing import TYPE_CHECKING, Any
from weakref import WeakKeyDictionary

from softplc.access import AccessError, AccessPort
from softplc.debug.registry import command, parse_value
from softplc.debug.stepper import DebugError
from softplc.twido.address import Ref

if TYPE_CHECKING:
    from softplc.debug.session import Session

_PORTS: WeakKeyDictionary[Any, AccessPort] = WeakKeyDictionary()  # one per PLC


def port_of(s: Session) -> AccessPort:
    """The access port of the session's PLC (made on first use, without scan hooks)."""
    port = _PORTS.get(s.plc)
    if port is None:
        port = _PORTS[s.plc] = AccessPort(s.plc, hooks=False)
    return port


@command("print", "p", formats=True)
def cmd_print(s: Session, arg: str, fmt: str = "") -> str:
    """print[/FMT] ADDR...: show objects or ranges: %MW0:15 (15 words from %MW0),
    %Q1.0:8 (8 bits), %MF40, %TM0, %C0, symbols (STARTS, STARTS:4, STAR_TIME.P).
    FMT: d decimal, u unsigned, x hex, b binary, f float (a word pair as %MF). Forced
    values are marked [forced]."""
    if not arg.strip():
        raise DebugError("print what? e.g. print %MW0, print/x %MW0:8")
    fmt = fmt.lower()
    if fmt not in ("", "d", "u", "x", "b", "f"):
        raise DebugError(f"unknown format /{fmt}: use /d /u /x /b /f")
    lines = []
    for a in arg.split():
        refs = s.parse_obj(a)
        if len(refs) == 1:
            lines.append(f"{s.title(refs[0])} = {s.show(refs[0], fmt)}")
            continue
        per = 8 if fmt in ("", "d", "u", "f") else 4
        port = port_of(s)
        forced = port.forced
        for i in range(0, len(refs), per):
            chunk = refs[i:i + per]
            vals = [s.fmt(r, v, fmt) + ("F" if str(r) in forced else "")
                    for r, v in zip(chunk, port.read_now(chunk), strict=True)]
            lines.append(f"{str(chunk[0]) + ':':<9} " + " ".join(f"{v:>6}" for v in vals))
        named = [s.title(r) for r in refs if r.symbol]  # the names a column cannot hold
        if named:
            lines.append("  symbols: " + ", ".join(named))
    return "\n".join(lines)


def _check_set(s: Session, refs: list[Ref], values: list[str]) -> list[tuple[Ref, Any]]:
    if len(values) != len(refs):
        raise DebugError(f"{len(refs)} object(s) but {len(values)} value(s)")
    port = port_of(s)
    out = []
    for ref, t in zip(refs, values, strict=True):
        # a debugger's set overrides devices, as a force does; %I: the field input
        why = port.why_not_writable(ref, forcing=True)
        if why is None and not (ref.writable or ref.kind == "I"):
            why = f"{s.title(ref)} is read-only"
        if why:
            raise DebugError(why)
        try:
            out.append((ref, port.check_value(ref, parse_value(t))))
        except AccessError as e:
            raise DebugError(str(e)) from None
    return out


@command("set")
def cmd_set(s: Session, arg: str) -> str:
    """set ADDR VALUE...: write an object at the start of the next scan (a range takes
    one value per object: set %MW0:3 1 2 3). %I writes go to the field input."""
    parts = arg.split()
    if len(parts) < 2:
        raise DebugError("set ADDR VALUE, e.g. set %MW3 120")
    items = _check_set(s, s.parse_obj(parts[0]), parts[1:])
    s.ctl.queue(items)
    return "queued for the next scan: " + ", ".join(f"{r} := {v}" for r, v in items)


@command("force")
def cmd_force(s: Session, arg: str) -> str:
    """force ADDR VALUE: hold an object at a value every scan (force alone lists)."""
    parts = arg.split()
    port = port_of(s)
    if not parts:
        f = port.forced
        return "\n".join(f"{k} = {v}" for k, v in f.items()) if f else "nothing forced"
    refs = s.parse_obj(parts[0])
    if len(refs) != 1:
        raise DebugError("force one object at a time")
    (ref, v), = _check_set(s, refs, parts[1:])
    if ref.offset is not None:
        raise DebugError("an indexed object cannot be forced")
    try:
        port.force(str(ref), v)
    except AccessError as e:
        raise DebugError(str(e)) from None
    port.apply_now()
    return f"{s.title(ref)} forced to {v}"


@command("unforce")
def cmd_unforce(s: Session, arg: str) -> str:
    """unforce [ADDR | all]: release a forced object (all without argument)."""
    port = port_of(s)
    if not arg or arg == "all":
        n = len(port.unforce())
        port.apply_now()
        return f"released {n} forced object(s)"
    ref = s.parse_obj(arg)[0]
    if str(ref) not in port.forced:
        raise DebugError(f"{s.title(ref)} is not forced")
    port.unforce(str(ref))
    port.apply_now()
    return f"{s.title(ref)} released"


@command("trace")
def cmd_trace(s: Session, arg: str) -> str:
    """trace ADDR... to FILE.csv: record these objects at the end of every scan from now
    on (trace off: stop)."""
    if arg.strip().lower() in ("off", "stop"):
        if s.trace_file is None:
            return "no trace running"
        name = s.trace_file.name
        s.close_trace()
        return f"trace to {name} stopped"
    m = re.match(r"(.+?)\s+to\s+(\S+)$", arg)
    if not m:
        raise DebugError("trace ADDR... to FILE.csv")
    refs = [r for a in m[1].split() for r in s.parse_obj(a)]
    s.close_trace()
    try:
        s.trace_file = open(m[2], "w", newline="", encoding="utf-8")  # noqa: SIM115
    except OSError as e:
        raise DebugError(f"cannot write {m[2]}: {_why(e, m[2])}") from None
    s.trace_writer = csv.writer(s.trace_file)
    s.trace_refs = refs
    s.trace_writer.writerow(["scan", "t"] + [str(r) for r in refs])
    return f"tracing {', '.join(map(str, refs))} to {m[2]} every scan"


def _why(e: OSError, path: str) -> str:
    """An OSError as words, e.g. "the folder /x does not exist"."""
    import errno
    import os

    folder = os.path.dirname(path) or "."
    if e.errno == errno.ENOENT:
        return f"the folder {folder} does not exist"
    if e.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if e.errno == errno.EISDIR:
        return "it is a folder"
    return e.strerror or str(e)
