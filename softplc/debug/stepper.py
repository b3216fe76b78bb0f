"""The debugger's stepper: runs the debug or the fast build scan by scan, rung by rung or
instruction by instruction, stops at breakpoints and watches, keeps the history of scans
(on `Engine` snapshots) for `back`. It returns data, never text: every run gives a `Ran`
(the typed reason it stopped, the hits, where it stands, the PLC's state); the REPL's
commands (`cmd_*.py`, over `session.Session`) format it (`report.py`). The web monitor
can drive the same stepper.
"""

from __future__ import annotations

import dataclasses
import re
from collections import deque
from collections.abc import Callable, Iterator
from enum import Enum
from typing import Any

from softplc.compiler.resolve import rungs_using
from softplc.errors import AddressError, SoftPLCError
from softplc.il import ast as A
from softplc.plc import PLC
from softplc.runtime.runstate import RUN
from softplc.twido.address import Ref
from softplc.twido.symbols import SymbolTable

HISTORY = 1000  # scans kept for `back`


class StopKind(Enum):
    """Why a run of the stepper ended."""

    DONE = "done"  # ran what was asked
    SCAN_END = "scan end"  # a step reached the end of the scan
    BREAKPOINT = "breakpoint"  # a rung breakpoint or a condition (hits: RungHit, CondHit)
    WATCH = "watch"  # a watched object changed (hits: WatchHit)
    INTERRUPTED = "interrupted"  # Ctrl-C
    FAULT = "fault"  # the PLC left RUN during the run (a fault: HALT)
    SCAN_LIMIT = "scan limit"  # `run_until_hit` ran its scans without a hit


# Reasons that end a repeated command (step 3, stepi 5, continue) early.
STOPS_A_COMMAND = frozenset({StopKind.BREAKPOINT, StopKind.WATCH, StopKind.INTERRUPTED,
                             StopKind.FAULT})


class BreakKind(Enum):
    """What a breakpoint waits for."""

    RUNG = "rung"  # a rung's start
    COND = "cond"  # a condition (becomes true, rises, falls, changes)
    WATCH = "watch"  # any change of an object (its changes are recorded)


class DebugError(SoftPLCError):
    """A command the debugger cannot do (bad argument, unknown rung...)."""


def pop_back(ring: deque[dict[str, Any]], n: int, unit: str) -> dict[str, Any]:
    """Drop the last n entries of a history ring (1 <= n); the oldest dropped, the state
    to go back to."""
    if n > len(ring):
        raise DebugError(f"only {len(ring)} {unit} of history")
    for _ in range(n - 1):
        ring.pop()
    return ring.pop()


@dataclasses.dataclass(frozen=True)
class Executed:
    """What a step ran: a scan's start (`rung` None), one instruction of the debug build
    (`rung`, `k`), or a whole scan of the fast build (`fast`); `scan_end`: the scan
    ended with it."""

    rung: int | None = None
    k: int | None = None
    fast: bool = False
    scan_end: bool = False


@dataclasses.dataclass(frozen=True)
class Position:
    """Where a run stands: scan count and PLC time, and the next instruction (`rung`,
    `k`), None at the scan boundary."""

    scan: int
    time: float
    rung: int | None = None
    k: int | None = None


@dataclasses.dataclass(frozen=True)
class RungHit:
    """A rung breakpoint reached (before the rung's first instruction)."""

    id: int
    rung: int
    text: str  # the rung's name


@dataclasses.dataclass(frozen=True)
class CondHit:
    """A condition became true (or rose, fell, changed)."""

    id: int
    text: str
    where: Executed


@dataclasses.dataclass(frozen=True)
class WatchHit:
    """A watched object changed: its values before and after."""

    id: int
    text: str
    old: Any
    new: Any
    where: Executed


Hit = RungHit | CondHit | WatchHit


@dataclasses.dataclass(frozen=True)
class Ran:
    """The result of a run: why it stopped, the breakpoints and watches that stopped it,
    where it stands, and the PLC's state and fault after it."""

    reason: StopKind
    position: Position
    running: bool  # the PLC is in RUN
    state: str
    fault: str | None = None
    hits: tuple[Hit, ...] = ()


@dataclasses.dataclass(frozen=True)
class Reloaded:
    """A program reload: whether a scan in progress was finished first, and the rung
    breakpoints disabled because their rung is gone."""

    finished: bool
    disabled: tuple[Breakpoint, ...] = ()


@dataclasses.dataclass
class Breakpoint:
    id: int
    kind: BreakKind
    text: str  # as shown in the list
    rung: int | None = None
    key: str = ""  # how the rung was named (re-resolved after reload)
    test: Callable[[], Any] | None = None  # cond: -> bool; watch: -> value
    mode: str = ""  # cond: "" (becomes true) | rises | falls | changes
    enabled: bool = True
    hits: int = 0
    last: Any = None


@dataclasses.dataclass
class Change:
    scan: int
    time: float
    where: Executed
    old: Any
    new: Any


@dataclasses.dataclass(frozen=True)
class _Stop:
    """Why a run stops early (inside `Stepper._run`)."""

    kind: StopKind
    hits: tuple[Hit, ...] = ()


def resolve_rung(program: A.Program, key: str, symbols: SymbolTable | None = None
                 ) -> A.Rung:
    """A rung named by number, title or label (%Li), or by an object (`%Q0.0`) or a
    symbol (`NEARLY_FULL`) it uses: the first rung that writes it, else the first that
    reads it."""
    key = key.strip()
    m = re.fullmatch(r"%L(\d+):?", key, re.I)
    if m:
        for r in program.rungs:
            if r.label == int(m[1]):
                return r
        raise DebugError(f"no label %L{m[1]} in the program")
    if not key:
        raise DebugError("which rung? a number, a title or a label %Li")
    try:
        return program.rung(key)
    except (KeyError, IndexError):
        pass
    last = len(program.rungs) - 1
    try:
        ref = symbols.ref(key) if symbols is not None else None
    except AddressError as e:
        assert symbols is not None
        raise DebugError(f"no rung {key!r} (rungs are 0..{last}; 'rungs' lists the titles)"
                         + (f"; {e}" if key.startswith("%") else
                            symbols.suggest(key.split(".")[0]))) from None
    if ref is None:
        raise DebugError(f"no rung {key!r} (rungs are 0..{last}; 'rungs' lists the titles)")
    found = rungs_using(program, ref)
    if not found:
        raise DebugError(f"no rung {key!r}: no title has it and no rung uses {ref.label}")
    return program.rungs[found[0]]


def _running(plc: PLC) -> bool:
    return plc.state == RUN


class Stepper:
    """Stepping, breakpoints and watches, history over one PLC."""

    def __init__(self, plc: PLC, history: int = HISTORY):
        self.plc = plc
        self.dbg = plc.compile_debug()
        self.dbg_version = plc.code_version
        self.gen: Iterator[tuple[int, int]] | None = None
        self.pos: tuple[int, int] | None = None  # next instruction (rung, k), None: boundary
        # snapshots, for `back`; history 0: none (a plant keeps its own), only the last
        # scan while a watch or condition may have to replay it
        self.history = history
        self.ring: deque[dict[str, Any]] = deque(maxlen=max(1, history))
        self.breakpoints = Breakpoints(plc)
        self.breaks = self.breakpoints.items  # (the same list and dict, kept in place)
        self.changes = self.breakpoints.changes  # watched objects' recorded changes
        self.pending: list[tuple[Ref, Any]] = []  # writes applied at the next scan start
        self.interrupted = False
        self.last_rung = 0
        self.executed = Executed()  # what the last step ran, for the watch history
        self.scan_end_hooks: list[Callable[[], None]] = []
        plc.before_scan.append(self._apply_pending)

    def _scan_end(self) -> None:
        for hook in self.scan_end_hooks:
            hook()

    def _restore(self, snap: dict[str, Any]) -> None:
        self.plc.engine.restore(snap["engine"])
        self.pending = list(snap["pending"])

    # ---- running ---------------------------------------------------------------------------------
    def _apply_pending(self) -> None:
        pending, self.pending = self.pending, []
        for ref, v in pending:
            self.plc[str(ref)] = v

    def _begin(self) -> None:
        """A scan starts: keep the state before it for `back` (and the replay of a
        fast scan where a watch or condition fired)."""
        if self.history or self.breakpoints.data:
            self.ring.append(self.snapshot())

    def snapshot(self) -> dict[str, Any]:
        """The state at a scan boundary (the engine's, the queued writes), for `rewind`."""
        return {"engine": self.plc.engine.snapshot(), "pending": list(self.pending)}

    def _tick(self) -> bool:
        """One step of the debug build: enter a scan (stop before its first instruction) or
        run the next instruction. True when a scan ended."""
        if self.gen is None:
            self._begin()
            if self.dbg_version != self.plc.code_version:  # rebuilt (force, reload)
                self.dbg = self.plc.compile_debug()
                self.dbg_version = self.plc.code_version
            self.gen = self.plc.engine.scan_stepwise(self.dbg.main)
            self.executed = Executed()
        else:
            r, k = self.pos
            self.executed = Executed(r, k)
        try:
            self.pos = next(self.gen)
            self.last_rung = self.pos[0]
            return False
        except StopIteration:
            self.gen, self.pos = None, None
            if self.executed.rung is not None:
                self.executed = dataclasses.replace(self.executed, scan_end=True)
            self._scan_end()
            return True

    def _fast_scan(self) -> None:
        self._begin()
        self.plc.engine.scan()
        self.executed = Executed(fast=True)
        self._scan_end()

    def _debug_scan(self) -> _Stop | None:
        """Run the debug build to the end of the scan (starting one if needed); a hit or an
        interrupt stops it early. Returns why it stopped early, else None."""
        while True:
            done = self._tick()
            stop = self.breakpoints.hits(self.pos, self.executed)
            if stop or done:
                return stop
            if self.interrupted:
                return _Stop(StopKind.INTERRUPTED)

    def _step(self, one_instr: bool) -> _Stop | None:
        """One instruction, or to the start of the next rung (a scan end stops both)."""
        start_rung = self.pos[0] if self.pos else None
        while True:
            done = self._tick()
            stop = self.breakpoints.hits(self.pos, self.executed)
            if stop:
                return stop
            if done:
                return _Stop(StopKind.SCAN_END)
            if one_instr or self.pos[0] != start_rung or self.interrupted:
                return None

    def _scans(self, scans: int, running: bool, power_flow: bool = True) -> _Stop | None:
        """Finish the scan in progress, then run `scans` whole scans; a hit, an interrupt
        or a fault (the PLC leaving RUN) stops them. `power_flow`: the last scan runs the
        debug build (for `rung N`)."""
        stop = self._debug_scan() if self.gen is not None else None
        remaining = scans
        debug = bool(self.breakpoints.at_rung)
        while remaining > 0 and not stop:
            if self.interrupted:
                stop = _Stop(StopKind.INTERRUPTED)
            elif running and not _running(self.plc):
                stop = _Stop(StopKind.FAULT)
            elif debug or (remaining == 1 and power_flow):  # feeds the power-flow view
                stop = self._debug_scan()
                if self.gen is None:
                    remaining -= 1
            else:
                self._fast_scan()
                bps = self.breakpoints
                if bps.data and bps.would_hit():
                    # replay the scan on the debug build to stop where it happened
                    self._restore(self.ring.pop())
                    stop = self._debug_scan()
                    if self.gen is None:
                        remaining -= 1
                else:
                    remaining -= 1
                    stop = self.breakpoints.hits(self.pos, self.executed)
        return stop

    def _run(self, scans: int | None, *, one_instr: bool = False,
             limit: bool = False, power_flow: bool = True) -> Ran:
        """The one driver. `scans`: whole scans to run after finishing the one in progress
        (`limit`: without a hit that is a SCAN_LIMIT); None: a step (one instruction, or
        to the next rung). Stops at breakpoints and when the PLC faults."""
        self.interrupted = False
        self.breakpoints.arm()
        running = _running(self.plc)
        stop = self._step(one_instr) if scans is None else \
            self._scans(scans, running, power_flow)
        if running and not _running(self.plc) and (stop is None or
                                                 stop.kind == StopKind.SCAN_END):
            stop = _Stop(StopKind.FAULT)
        elif limit and stop is None:
            stop = _Stop(StopKind.SCAN_LIMIT)
        return Ran(stop.kind if stop else StopKind.DONE, self.position(), _running(self.plc),
                   self.plc.state, self.plc.fault, stop.hits if stop else ())

    def position(self) -> Position:
        """Where the run is: the scan boundary or the next instruction."""
        r, k = self.pos if self.pos is not None else (None, None)
        return Position(self.plc.scan_count, self.plc.time, r, k)

    # -- the public driving API (the REPL's commands and the web monitor use these) ----------
    def step(self) -> Ran:
        """Run to the start of the next rung (entering a scan if at the boundary)."""
        return self._run(None)

    def step_instruction(self) -> Ran:
        """Run one instruction (entering a scan if at the boundary)."""
        return self._run(None, one_instr=True)

    def run_scans(self, n: int, power_flow: bool = True) -> Ran:
        """Finish the scan in progress, then run n whole scans (0: only finish it);
        breakpoints stop it. `power_flow` False: the fast build unless a breakpoint needs
        the debug one (a plant runs each controller scan by scan)."""
        return self._run(n, power_flow=power_flow)

    def run_until_hit(self, limit: int) -> Ran:
        """Run until a breakpoint or watch stops it, at most `limit` scans (SCAN_LIMIT)."""
        return self._run(limit, limit=True)

    @property
    def in_scan(self) -> bool:
        """A scan is in progress (stopped before one of its instructions)."""
        return self.gen is not None

    def interrupt(self) -> None:
        """Ask a running run to stop at the next scan or instruction (Ctrl-C)."""
        self.interrupted = True

    def queue(self, items: list[tuple[Ref, Any]]) -> None:
        """Writes applied at the start of the next scan."""
        self.pending.extend(items)

    # -- program and history ---------------------------------------------------------------
    def reload(self, program: A.Program) -> Reloaded:
        """Run `program` from now on, keeping memory; a scan in progress is finished first.
        Rung breakpoints follow their rung (by how it was named) or are disabled."""
        finished = self.in_scan
        if finished:
            self._run(0)
        self.plc.replace_program(program)
        self.dbg = self.plc.compile_debug()
        self.dbg_version = self.plc.code_version
        lost = []
        for b in self.breaks:
            if b.kind == BreakKind.RUNG:
                try:
                    r = resolve_rung(program, b.key, self.plc.symbols)
                    b.rung, b.text = r.index, r.name
                except DebugError:
                    b.enabled = False
                    lost.append(b)
        self.last_rung = min(self.last_rung, max(0, len(program.rungs) - 1))
        return Reloaded(finished, tuple(lost))

    def back(self, n: int) -> None:
        """Go back n scans (1 <= n <= len(ring); a scan in progress counts as one)."""
        self.rewind(pop_back(self.ring, n, "scans"))

    def rewind(self, snap: dict[str, Any]) -> None:
        """Back to a `snapshot()`: a scan in progress is abandoned, the writes queued
        since stay queued, the watches forget the changes after it."""
        if self.gen is not None:
            self.gen.close()
            self.gen, self.pos = None, None
        queued = self.pending  # sets typed since the last scan stay queued
        self._restore(snap)
        self.pending += [q for q in queued if q not in self.pending]
        for hist in self.changes.values():  # changes from the undone scans are gone
            while hist and hist[-1].scan >= self.plc.scan_count:
                hist.pop()
        for b in self.breaks:
            if b.test is not None:
                try:
                    b.last = b.test()
                except SoftPLCError:
                    pass

    def close(self) -> None:
        if self.gen is not None:
            self.gen.close()
            self.gen = None
        if self._apply_pending in self.plc.before_scan:
            self.plc.before_scan.remove(self._apply_pending)


class Breakpoints:
    """The breakpoints and watches of a debugging session, with the watches' recorded
    changes, and the checks a run makes with them."""

    def __init__(self, plc: PLC):
        self.plc = plc
        self.items: list[Breakpoint] = []
        self.changes: dict[str, deque[Change]] = {}
        self.next_id = 1  # of the next breakpoint
        self.at_rung: dict[int | None, Breakpoint] = {}  # enabled rung breakpoints (arm)
        self.data = False  # any watch or condition (arm)

    def add(self, **kw: Any) -> Breakpoint:
        """A new breakpoint or watch (see `Breakpoint`); a watch records its changes."""
        b = Breakpoint(self.next_id, **kw)
        self.next_id += 1
        if b.test is not None:
            b.last = b.test()
        self.items.append(b)
        if b.kind == BreakKind.WATCH:
            self.changes.setdefault(b.text, deque(maxlen=HISTORY))
        return b

    def find(self, ids: list[int] | None) -> list[Breakpoint]:
        """The breakpoints with these ids (all for None)."""
        if ids is None:
            return list(self.items)
        out = []
        for i in ids:
            b = next((b for b in self.items if b.id == i), None)
            if b is None:
                raise DebugError(f"no breakpoint #{i}")
            out.append(b)
        return out

    def delete(self, gone: list[Breakpoint]) -> None:
        self.items[:] = [b for b in self.items if b not in gone]

    def arm(self) -> None:
        """Index the breakpoints for the per-instruction checks of a run."""
        self.at_rung = {}
        for b in self.items:
            if b.kind == BreakKind.RUNG and b.enabled:
                self.at_rung.setdefault(b.rung, b)
        self.data = any(b.kind != BreakKind.RUNG for b in self.items)

    def hits(self, pos: tuple[int, int] | None, executed: Executed) -> _Stop | None:
        """Why to stop here (breakpoints, watches), or None."""
        hits: list[Hit] = list(self.check_data(executed)) if self.data else []
        if pos is not None and pos[1] == 0:
            b = self.at_rung.get(pos[0])
            if b is not None:
                b.hits += 1
                hits.insert(0, RungHit(b.id, pos[0], b.text))
        if not hits:
            return None
        kind = StopKind.WATCH if all(isinstance(h, WatchHit) for h in hits) \
            else StopKind.BREAKPOINT
        return _Stop(kind, tuple(hits))

    def _values(self) -> Iterator[tuple[Breakpoint, Any]]:
        """Each watch and condition with its value now (those that cannot be read skipped)."""
        for b in self.items:
            if b.kind == BreakKind.RUNG or b.test is None:
                continue
            try:
                yield b, b.test()
            except SoftPLCError:
                continue

    @staticmethod
    def _fires(b: Breakpoint, old: Any, new: Any) -> bool:
        """Whether a watch or condition going from `old` to `new` stops a run."""
        if b.kind == BreakKind.WATCH or b.mode == "changes":
            return new != old
        if b.mode == "falls":
            return bool(old) and not new
        return bool(new) and not old  # becomes true, rises

    def would_hit(self) -> bool:
        """Whether a watch or condition would stop a run now (nothing recorded)."""
        return any(b.enabled and self._fires(b, b.last, v) for b, v in self._values())

    def check_data(self, executed: Executed) -> list[CondHit | WatchHit]:
        """Watches and conditions after a step or a scan: record the watches' changes,
        return those that stop the run."""
        hits: list[CondHit | WatchHit] = []
        for b, v in self._values():
            old, b.last = b.last, v
            if b.kind == BreakKind.WATCH and v != old:
                self.changes.setdefault(b.text, deque(maxlen=HISTORY)).append(
                    Change(self.plc.scan_count, self.plc.time, executed, old, v))
            if b.enabled and self._fires(b, old, v):
                b.hits += 1
                hits.append(WatchHit(b.id, b.text, old, v, executed) if b.kind == BreakKind.WATCH
                            else CondHit(b.id, b.text, executed))
        return hits
