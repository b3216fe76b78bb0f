"""The debugger over a whole plant (issue 35): every controller of a `Plant` stepped
together on the plant's one clock.

    s = PlantSession(Plant.from_file("ladder_programs/plant/plant.toml"))
    s.execute("set master:%I0.0 1")
    s.execute("break filler:%Q0.0")     # a rung of the filler's program
    s.execute("continue")               # the whole plant stops at that scan
    s.execute("back 3")                 # every controller, the belt and the link

Each controller keeps its own `Session` (its breakpoints, watches, forced objects, queued
writes); this class runs the plant's instants (`Plant.begin_step`) and the scans due at
each one through those sessions' steppers, in the plant's order, so that a breakpoint in
any controller stops the plant inside that scan; the controllers after it in the file's
order scan when the instant is finished. Commands naming `NAME:OBJECT` go to controller
NAME's session with the object unqualified; others to the focused controller's (`ctl
NAME`; a breakpoint moves the focus to the controller it stopped). `back N` restores the
plant's checkpoint of N instants ago: every engine (its memory, clock, devices), the queued
writes, the shared devices and the Remote Link (cycles, stations, words in flight).
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from softplc.config import duration
from softplc.debug.report import position_text, run_text
from softplc.debug.session import CONTINUE_LIMIT, Session
from softplc.debug.stepper import (
    HISTORY,
    STOPS_A_COMMAND,
    DebugError,
    Ran,
    StopKind,
    pop_back,
)
from softplc.errors import ConfigError, SoftPLCError
from softplc.plant import Plant
from softplc.plant.history import checkpoint, rewind
from softplc.runtime.runstate import RUN

# NAME:REST where NAME may be a controller or a device (not a %-address: `%MW0:15` is a
# range, `%L3:` a label)
QUALIFIED = re.compile(r"(?<![\w%#])([A-Za-z_][\w-]*):(?=\S)")
# the one-controller commands that make no sense on one controller of a plant
NOT_IN_A_PLANT = {"reload": "reload is not available in a plant (restart with the new "
                            "program)"}


@dataclass
class Stopped:
    """Why a plant run stopped early: the controller and its stepper's result."""

    name: str
    ran: Ran


PlantCommand = Callable[["PlantSession", str], str]
PLANT_COMMANDS: dict[str, tuple[PlantCommand, str]] = {}
PLANT_ALIASES: dict[str, str] = {}


def plant_command(name: str, *aliases: str) -> Callable[[PlantCommand], PlantCommand]:
    """Register a command of the plant debugger (its docstring is its `help` line)."""
    def register(fn: PlantCommand) -> PlantCommand:
        PLANT_COMMANDS[name] = (fn, " ".join((fn.__doc__ or "").split()))
        PLANT_ALIASES.update(dict.fromkeys(aliases, name))
        return fn
    return register


class PlantSession:
    """A debugging session over a plant; `execute(line)` returns the text to show."""

    def __init__(self, plant: Plant, history: int = HISTORY):
        self.plant = plant
        # no history of a controller's own (history 0): the plant keeps every instant's
        self.sessions = {name: Session(c.plc, c.program, history=0)
                         for name, c in plant.controllers.items()}
        self.focus = next(iter(self.sessions))
        self.ring: deque[dict[str, Any]] = deque(maxlen=history)
        self.due: list[str] = []  # controllers still to scan at this instant
        self.held: str | None = None  # the controller stopped inside its scan
        self.instants = 0
        self.interrupted = False
        self.continue_limit = CONTINUE_LIMIT  # instants `continue` runs before giving up
        self.done = False
        self.width = 80

    # ---- the command line ----------------------------------------------------------------
    @property
    def session(self) -> Session:
        """The focused controller's session."""
        return self.sessions[self.focus]

    def execute(self, line: str) -> str:
        """Run one command line; errors come back as text."""
        line = line.strip()
        if not line or line.startswith("#"):
            return ""
        word, _, rest = line.partition(" ")
        name = PLANT_ALIASES.get(word.lower(), word.lower())
        try:
            if name in PLANT_COMMANDS:
                return PLANT_COMMANDS[name][0](self, rest.strip())
            if name in NOT_IN_A_PLANT:
                raise DebugError(NOT_IN_A_PLANT[name])
            owner, rest = self.unqualify(rest)
            if owner in self.plant.devices:
                return self._device(word, owner, rest)
            return self.sessions[owner or self.focus].execute(f"{word} {rest}".strip())
        except (SoftPLCError, ValueError, KeyError) as e:
            return f"error: {e.args[0] if isinstance(e, KeyError) and e.args else e}"

    def unqualify(self, rest: str) -> tuple[str | None, str]:
        """The controller (or device) a command's objects name, and the arguments without
        `NAME:`; one owner per command."""
        owners = set()

        def strip(m: re.Match[str]) -> str:
            if m[1] in self.sessions or m[1] in self.plant.devices:
                owners.add(m[1])
                return ""
            return m[0]
        out = QUALIFIED.sub(strip, rest)
        if len(owners) > 1:
            raise DebugError(f"one controller per command ({', '.join(sorted(owners))})")
        return (owners.pop() if owners else None), out

    def _device(self, word: str, device: str, signal: str) -> str:
        if word.lower() not in ("print", "p"):
            raise DebugError(f"{device} is a shared device: only `print {device}:SIGNAL` "
                             f"(its signals are moved by the plant)")
        return f"{device}:{signal} = {int(self.plant[f'{device}:{signal}'])}"

    @property
    def plc(self) -> Any:
        """The focused controller's PLC (the REPL completes its rung titles)."""
        return self.session.plc

    @property
    def aliases(self) -> dict[str, str]:
        return {**self.session.aliases, **PLANT_ALIASES}

    def addresses(self) -> list[str]:
        """The focused controller's objects, for tab completion."""
        return self.session.addresses()

    def complete_words(self) -> list[str]:
        return sorted(set(PLANT_COMMANDS) | set(self.session.complete_words()))

    def interrupt(self) -> None:
        """Ctrl-C: stop a running plant at the next instant or instruction."""
        self.interrupted = True
        for s in self.sessions.values():
            s.interrupt()

    # ---- running -------------------------------------------------------------------------
    def _instant(self) -> Stopped | None:
        """Run an instant of the plant, or the rest of the one in progress: a breakpoint,
        a watch or a fault in a controller's scan stops it there."""
        if not self.due:
            self.ring.append(self._checkpoint())
            self.due = [c.name for c in self.plant.begin_step()]
            self.instants += 1
        while self.due:
            name = self.due[0]
            ctl = self.sessions[name].ctl
            if name == self.held and not ctl.in_scan:  # a `step` finished its scan
                ran = None
            else:
                ran = ctl.run_scans(0 if ctl.in_scan else 1, power_flow=False)
            self.held = name if ctl.in_scan else None
            if not ctl.in_scan:
                self.due.pop(0)
            if ran is not None and ran.reason in STOPS_A_COMMAND:
                return Stopped(name, ran)
        return None

    def advance(self, more: Callable[[], bool], limit: int = CONTINUE_LIMIT
                ) -> Stopped | None:
        """Finish the instant in progress, then run instants while `more()` (asked at
        each instant's end), at most `limit`; a breakpoint, watch, fault or Ctrl-C stops
        them."""
        self.interrupted = False
        stop = self._instant() if self.due else None
        n = 0
        while stop is None and n < limit and more():
            if self.interrupted:
                ctl = self.sessions[self.focus].ctl
                return Stopped(self.focus, Ran(StopKind.INTERRUPTED, ctl.position(),
                                               ctl.plc.state == RUN, ctl.plc.state,
                                               ctl.plc.fault))
            stop = self._instant()
            n += 1
        if stop is not None:
            self.focus = stop.name
        return stop

    def scans_of(self, name: str, n: int) -> Stopped | None:
        """Finish the instant in progress, then run until controller `name` has run n
        more scans."""
        c = self.plant.controllers[name]
        if n and not c.alive:
            raise DebugError(f"{name} is off: it runs no scans")
        stop = self.advance(lambda: False) if self.due else None
        if stop is not None or not n:
            return stop
        end = c.plc.scan_count + n
        return self.advance(lambda: c.plc.scan_count < end)

    def back(self, n: int) -> None:
        """Back n instants (the one in progress counts as one)."""
        cp = pop_back(self.ring, n, "instants")
        rewind(self.plant, cp["plant"])
        for name, snap in cp["controllers"].items():
            self.sessions[name].ctl.rewind(snap)
        self.due, self.held = [], None
        self.instants -= n

    def _checkpoint(self) -> dict[str, Any]:
        return {"plant": checkpoint(self.plant),
                "controllers": {n: s.ctl.snapshot() for n, s in self.sessions.items()}}

    # ---- texts ---------------------------------------------------------------------------
    def where(self) -> str:
        """The plant's time and instant, where the focused controller stands, and the
        scans still due at this instant."""
        s = self.session
        head = f"[plant t = {self.plant.time:.3f} s, instant {self.instants}] {self.focus}: "
        text = head + position_text(s.ctl.position(), s.plc.ast)
        rest = [n for n in self.due if n != self.held]
        if self.held is not None and self.held != self.focus:
            text += f"\n{self.held} is stopped inside its scan"
        if rest:
            text += f"\nstill to scan at this instant: {', '.join(rest)}"
        return text

    def result(self, stop: Stopped | None) -> str:
        if stop is None:
            return self.where()
        s = self.sessions[stop.name]
        lines = run_text(stop.ran, s.plc.ast).splitlines()[:-1]  # its position: where()
        return "\n".join([f"[{stop.name}] " + line for line in lines] + [self.where()])

    def close(self) -> None:
        for s in self.sessions.values():
            s.close()


# ---- the plant's commands ----------------------------------------------------------------
def _count(arg: str, default: int) -> int:
    if not arg:
        return default
    if not re.fullmatch(r"\d{1,9}", arg):
        raise DebugError(f"{arg!r} is not a count (a whole number >= 0)")
    return int(arg)


@plant_command("step", "s")
def cmd_step(p: PlantSession, arg: str) -> str:
    """step [N]: inside a scan stopped at a breakpoint (of the focused controller), to
    the next rung; at the plant's boundary, the plant's next instant (a scan, link cycle
    or device tick due)."""
    return _step(p, arg, "step")


@plant_command("stepi", "si")
def cmd_stepi(p: PlantSession, arg: str) -> str:
    """stepi [N]: inside a stopped scan, one instruction; else as step."""
    return _step(p, arg, "stepi")


def _step(p: PlantSession, arg: str, word: str) -> str:
    n = _count(arg, 1)
    if p.held is not None and p.held == p.focus:
        out = p.session.execute(f"{word} {n}")
        if not p.session.ctl.in_scan:  # its scan is over: the instant goes on from here
            out += "\n" + p.result(p.advance(lambda: False))
        return out
    left = [n]

    def more() -> bool:
        left[0] -= 1
        return left[0] >= 0
    return p.result(p.advance(more))


@plant_command("scan")
def cmd_scan(p: PlantSession, arg: str) -> str:
    """scan [N]: finish the plant's instant in progress, then run the plant until the
    focused controller has run N more scans (default 1; 0 while an instant is in
    progress); every controller, link and device advances with it. Stops at
    breakpoints."""
    return p.result(p.scans_of(p.focus, _count(arg, 0 if p.due else 1)))


@plant_command("run", "r")
def cmd_run(p: PlantSession, arg: str) -> str:
    """run N | run Ts: N scans of the focused controller, or T seconds of plant time
    (run 2s, run 500ms: every instant up to the plant's time + T). Stops at
    breakpoints."""
    if not arg:
        raise DebugError("run N (scans) or run T (seconds of plant time, e.g. 2s, 500ms)")
    if re.fullmatch(r"\d{1,9}", arg):
        return p.result(p.scans_of(p.focus, int(arg)))
    try:
        secs = duration(arg, "run")
    except ConfigError as e:
        raise DebugError(str(e)) from None
    end = p.plant.now_us + round(secs * 1e6)
    return p.result(p.advance(lambda: p.plant.next_time() <= end))  # up to now + T


@plant_command("continue", "c", "cont")
def cmd_continue(p: PlantSession, arg: str) -> str:
    """continue: run the plant until a breakpoint or watch of any controller stops it
    (at most 100000 instants)."""
    if not any(b.enabled for s in p.sessions.values() for b in s.ctl.breaks):
        raise DebugError("no breakpoint is enabled in any controller: continue would never "
                         "stop (use 'run N' or set one with 'break NAME:RUNG')")
    stop = p.advance(lambda: True, p.continue_limit)
    if stop is None:
        return f"no breakpoint hit in {p.continue_limit} instants\n" + p.where()
    return p.result(stop)


@plant_command("back")
def cmd_back(p: PlantSession, arg: str) -> str:
    """back [N]: the whole plant N instants back (default 1; an instant in progress
    counts as one): every controller, the shared devices, the Remote Link."""
    n = _count(arg, 1)
    if n:
        p.back(n)
    return p.where()


@plant_command("ctl", "controller")
def cmd_ctl(p: PlantSession, arg: str) -> str:
    """ctl [NAME]: focus controller NAME (its objects are then named without NAME:);
    without NAME: list the controllers."""
    if not arg:
        lines = []
        for name, c in p.plant.controllers.items():
            mark = "*" if name == p.focus else " "
            state = c.plc.state if c.alive else "OFF"
            lines.append(f"{mark} {name:12s} {state}  scans {c.plc.scan_count}  "
                         f"{c.program or 'remote I/O'}")
        return "\n".join(lines)
    if arg not in p.sessions:
        raise DebugError(f"no controller {arg!r} (controllers: {', '.join(p.sessions)})")
    p.focus = arg
    return p.where()


@plant_command("link")
def cmd_link(p: PlantSession, arg: str) -> str:
    """link [NAME]: the Remote Link as each controller on it sees it (the station, its
    %SW111-%SW113, the words %INW / %QNW); NAME: that controller only."""
    if arg and arg not in p.sessions:
        raise DebugError(f"no controller {arg!r} (controllers: {', '.join(p.sessions)})")
    names = [arg] if arg else [n for n, c in p.plant.controllers.items() if c.link]
    if not names:
        return "no Remote Link in this plant"
    return "\n".join(f"{n}: " + p.sessions[n].execute("link") for n in names)


@plant_command("where", "bt")
def cmd_where(p: PlantSession, arg: str) -> str:
    """where: the plant's time, the focused controller's position, the scans still due."""
    return p.where()


@plant_command("plant")
def cmd_plant(p: PlantSession, arg: str) -> str:
    """plant: every controller's state, scans and link status; each device's status."""
    st = p.plant.status()
    lines = [f"{p.plant.name}: t = {st['time']:.3f} s, {p.instants} instants"]
    for name, c in st["controllers"].items():
        link = c["link"]
        health = "" if link is None else \
            f"  link %SW111=16#{link['status']:04X} %SW112={link['error']}"
        lines.append(f"  {name:12s} {c['state']}  {c['scans']} scans{health}")
    for name, d in st["devices"].items():
        lines.append(f"  {name:12s} " + " ".join(f"{k}={v}" for k, v in d.items()))
    return "\n".join(lines)


@plant_command("help", "h")
def cmd_help(p: PlantSession, arg: str) -> str:
    """help: the plant's commands, then the controller's (NAME:OBJECT names an object of
    controller NAME, a plain object one of the focused controller)."""
    if arg and arg not in PLANT_COMMANDS and arg not in PLANT_ALIASES:
        return p.session.execute(f"help {arg}")
    lines = ["the plant:"] + [f"  {doc}" for _, doc in PLANT_COMMANDS.values()]
    own = sorted(n for n in p.session.complete_words() if n not in PLANT_COMMANDS)
    lines += ["each controller's own (help NAME for one): " + ", ".join(own),
              "  they act on the focused controller (ctl NAME), or on NAME's with "
              "NAME:OBJECT: print filler:%MW0, break capper:%Q0.0, set master:%I0.0 1,",
              "  delete filler:2; print DEVICE:SIGNAL shows a shared device's signal"]
    return "\n".join(lines)


@plant_command("breakpoints", "breaks", "tb")
def cmd_breakpoints(p: PlantSession, arg: str) -> str:
    """breakpoints: every controller's breakpoints and watches."""
    out = []
    for name, s in p.sessions.items():
        if s.ctl.breaks:
            out += [f"{name}: {line}" for line in s.execute("breakpoints").splitlines()]
    return "\n".join(out) or "no breakpoints"


@plant_command("delete", "d")
def cmd_delete(p: PlantSession, arg: str) -> str:
    """delete [ID... | NAME:ID...]: delete the focused (or NAME's) controller's
    breakpoints; without argument every controller's."""
    return _each(p, "delete", arg)


@plant_command("disable")
def cmd_disable(p: PlantSession, arg: str) -> str:
    """disable [ID... | NAME:ID...]: as delete, disabling."""
    return _each(p, "disable", arg)


@plant_command("enable")
def cmd_enable(p: PlantSession, arg: str) -> str:
    """enable [ID... | NAME:ID...]: as delete, enabling."""
    return _each(p, "enable", arg)


def _each(p: PlantSession, word: str, arg: str) -> str:
    if arg:
        owner, rest = p.unqualify(arg)
        return p.sessions[owner or p.focus].execute(f"{word} {rest}")
    return "\n".join(f"{name}: {s.execute(word)}" for name, s in p.sessions.items())


@plant_command("quit", "q", "exit")
def cmd_quit(p: PlantSession, arg: str) -> str:
    """quit: leave the debugger."""
    p.done = True
    return ""


__all__ = ["PLANT_COMMANDS", "PlantSession", "Stopped"]
