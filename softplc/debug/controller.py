"""The stepping controller of the debugger: runs the debug or the fast build scan by scan,
rung by rung or instruction by instruction, stops at breakpoints and watches, keeps the
history of scans (on `Engine` snapshots) for `back`. No terminal I/O: every run returns a
typed reason (`Ran.reason`) with the text to show. The REPL's command layer
(`session.Session`) holds one and drives it through the public methods below; the web
monitor can drive the same controller.
"""

from __future__ import annotations

import dataclasses
import re
from collections import deque
from collections.abc import Callable, Iterator
from enum import Enum
from typing import Any

from ..address import Ref
from ..display import format_value
from ..errors import SoftPLCError
from ..il import ast as A
from ..il.printer import format_instruction
from ..plc import PLC
from ..runtime.runstate import RUN

HISTORY = 1000  # scans kept for `back`


class StopKind(Enum):
    """Why a run of the stepping controller ended."""

    DONE = "done"  # ran what was asked
    SCAN_END = "scan end"  # a step reached the end of the scan
    BREAKPOINT = "breakpoint"
    WATCH = "watch"
    INTERRUPTED = "interrupted"  # Ctrl-C


# Reasons that end a repeated command (step 3, stepi 5, continue) early.
STOPS_A_COMMAND = frozenset({StopKind.BREAKPOINT, StopKind.WATCH, StopKind.INTERRUPTED})


class DebugError(SoftPLCError):
    """A command the debugger cannot do (bad argument, unknown rung...)."""


@dataclasses.dataclass(frozen=True)
class Stop:
    kind: StopKind
    message: str = ""


@dataclasses.dataclass(frozen=True)
class Ran:
    """The result of a run: the typed reason it stopped and the text for the user."""

    reason: StopKind
    text: str


@dataclasses.dataclass
class Breakpoint:
    id: int
    kind: str  # rung | cond | watch
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
    where: str
    old: Any
    new: Any


class Controller:
    """Stepping, breakpoints and watches, history over one PLC."""

    def __init__(self, plc: PLC, history: int = HISTORY):
        self.plc = plc
        self.dbg = plc.compile_debug()
        self.dbg_version = plc.program_version
        self.gen: Iterator[tuple[int, int]] | None = None
        self.pos: tuple[int, int] | None = None  # next instruction (rung, k), None: boundary
        self.ring: deque[dict[str, Any]] = deque(maxlen=history)  # snapshots, for `back`
        self.breakpoints = Breakpoints(plc)
        self.breaks = self.breakpoints.items  # (the same list and dict, kept in place)
        self.changes = self.breakpoints.changes  # watched objects' recorded changes
        self.pending: list[tuple[Ref, Any]] = []  # writes applied at the next scan start
        self.interrupted = False
        self.last_rung = 0
        self.ran = ""  # what the last step ran, for the watch history
        self.scan_end_hooks: list[Callable[[], None]] = []
        plc.before_scan.append(self._apply_pending)

    def _scan_end(self) -> None:
        for hook in self.scan_end_hooks:
            hook()

    def _snapshot(self) -> dict[str, Any]:
        return {"engine": self.plc.engine.snapshot(), "pending": list(self.pending)}

    def _restore(self, snap: dict[str, Any]) -> None:
        self.plc.engine.restore(snap["engine"])
        self.pending = list(snap["pending"])

    # ---- running ---------------------------------------------------------------------------------
    def _apply_pending(self) -> None:
        pending, self.pending = self.pending, []
        for ref, v in pending:
            self.plc[str(ref)] = v

    def _begin(self) -> None:
        self.ring.append(self._snapshot())

    def _tick(self) -> bool:
        """One step of the debug build: enter a scan (stop before its first instruction) or
        run the next instruction. True when a scan ended."""
        if self.gen is None:
            self._begin()
            if self.dbg_version != self.plc.program_version:  # rebuilt (force, reload)
                self.dbg = self.plc.compile_debug()
                self.dbg_version = self.plc.program_version
            self.gen = self.plc.engine.scan_stepwise(self.dbg.main)
            self.ran = "scan start"
        else:
            r, k = self.pos
            self.ran = f"rung {r} instr {k}"
        try:
            self.pos = next(self.gen)
            self.last_rung = self.pos[0]
            return False
        except StopIteration:
            self.gen, self.pos = None, None
            self.ran += " + scan end" if self.ran != "scan start" else ""
            self._scan_end()
            return True

    def _fast_scan(self) -> None:
        self._begin()
        self.plc.engine.scan()
        self.ran = "scan"
        self._scan_end()

    def _debug_scan(self) -> Stop | None:
        """Run the debug build to the end of the scan (starting one if needed); a hit or an
        interrupt stops it early. Returns why it stopped early, else None."""
        while True:
            done = self._tick()
            stop = self.breakpoints.hits(self.pos, self.ran)
            if stop or done:
                return stop
            if self.interrupted:
                return Stop(StopKind.INTERRUPTED, "interrupted")

    def _run(self, scans: int | None, *, until_rung_change: bool = False,
             one_instr: bool = False) -> Ran:
        """The one driver. `scans`: whole scans to run after finishing the one in progress;
        None: a step (one instruction, or to the next rung). Stops at breakpoints. Returns
        why it stopped (a typed reason) and the text for the user."""
        self.interrupted = False
        self.breakpoints.arm()
        stop: Stop | None = None
        if scans is None:
            start_rung = self.pos[0] if self.pos else None
            while True:
                done = self._tick()
                stop = self.breakpoints.hits(self.pos, self.ran)
                if stop:
                    break
                if done:
                    stop = Stop(StopKind.SCAN_END, f"scan {self.plc.scan_count} complete")
                    break
                if one_instr or self.pos[0] != start_rung or self.interrupted:
                    break
        else:
            if self.gen is not None:
                stop = self._debug_scan()
            remaining = scans
            debug = bool(self.breakpoints.at_rung)
            while remaining > 0 and not stop:
                if self.interrupted:
                    stop = Stop(StopKind.INTERRUPTED, "interrupted")
                elif debug or remaining == 1:  # the last scan feeds the power-flow view
                    stop = self._debug_scan()
                    if self.gen is None:
                        remaining -= 1
                else:
                    self._fast_scan()
                    bps = self.breakpoints
                    if bps.data and bps.check_data(self.ran, commit=False):
                        # replay the scan on the debug build to stop where it happened
                        self._restore(self.ring.pop())
                        stop = self._debug_scan()
                        if self.gen is None:
                            remaining -= 1
                    else:
                        remaining -= 1
                        stop = self.breakpoints.hits(self.pos, self.ran)
        msgs = [stop.message] if stop else []
        if self.plc.state != RUN:
            msgs.append(f"PLC in {self.plc.state}" + (f": {self.plc.fault}"
                                                        if self.plc.fault else ""))
        msgs.append(self.position())
        return Ran(stop.kind if stop else StopKind.DONE, "\n".join(msgs))

    def position(self) -> str:
        """Where the run is: the scan boundary or the next instruction, as text."""
        t = f"scan {self.plc.scan_count}, t = {self.plc.time:.3f} s"
        if self.pos is None:
            return f"[{t}] at the scan boundary"
        r, k = self.pos
        rung = self.plc.ast.rungs[r]
        ins = rung.instructions[k] if k < len(rung.instructions) else None
        text = format_instruction(ins) if ins is not None else ""
        title = f" ({rung.title})" if rung.title else ""
        return f"[{t}] before rung {r}{title} instr {k}: {text}"

    # -- the public driving API (the REPL's commands and the web monitor use these) ----------
    def step(self) -> Ran:
        """Run to the start of the next rung (entering a scan if at the boundary)."""
        return self._run(None, until_rung_change=True)

    def step_instruction(self) -> Ran:
        """Run one instruction (entering a scan if at the boundary)."""
        return self._run(None, one_instr=True)

    def run_scans(self, n: int) -> Ran:
        """Finish the scan in progress, then run n whole scans; breakpoints stop it."""
        return self._run(n)

    @property
    def in_scan(self) -> bool:
        """A scan is in progress (stopped before one of its instructions)."""
        return self.gen is not None

    def finish_scan(self) -> Ran:
        """Run the scan in progress to its end (breakpoints stop it)."""
        return self._run(0)

    def interrupt(self) -> None:
        """Ask a running run to stop at the next scan or instruction (Ctrl-C)."""
        self.interrupted = True

    def queue(self, items: list[tuple[Ref, Any]]) -> None:
        """Writes applied at the start of the next scan."""
        self.pending.extend(items)

    # -- breakpoints and watches ---------------------------------------------------------------
    def resolve_rung(self, key: str) -> A.Rung:
        """A rung named by number, title or label (%Li)."""
        key = key.strip()
        m = re.fullmatch(r"%L(\d+):?", key, re.I)
        if m:
            for r in self.plc.ast.rungs:
                if r.label == int(m[1]):
                    return r
            raise DebugError(f"no label %L{m[1]} in the program")
        if not key:
            raise DebugError("which rung? a number, a title or a label %Li")
        try:
            return self.plc.ast.rung(key)
        except (KeyError, IndexError):
            raise DebugError(f"no rung {key!r} (rungs are 0..{len(self.plc.ast.rungs) - 1}; "
                             f"'rungs' lists the titles)") from None

    def reload(self, program: A.Program) -> tuple[bool, list[str]]:
        """Run `program` from now on, keeping memory; a scan in progress is finished first.
        Rung breakpoints follow their rung (by how it was named) or are disabled. Returns
        whether a scan was finished and the breakpoints disabled (as text)."""
        finished = self.in_scan
        if finished:
            self._run(0)
        self.plc.replace_program(program)
        self.dbg = self.plc.compile_debug()
        self.dbg_version = self.plc.program_version
        lost = []
        for b in self.breaks:
            if b.kind == "rung":
                try:
                    r = self.resolve_rung(b.key)
                    b.rung, b.text = r.index, r.name
                except DebugError:
                    b.enabled = False
                    lost.append(f"breakpoint #{b.id} ({b.key}) disabled: no such rung now")
        self.last_rung = min(self.last_rung, max(0, len(program.rungs) - 1))
        return finished, lost

    def back(self, n: int) -> None:
        """Go back n scans (1 <= n <= len(ring); a scan in progress counts as one)."""
        if n > len(self.ring):
            raise DebugError(f"only {len(self.ring)} scans of history")
        if self.gen is not None:
            self.gen.close()
            self.gen, self.pos = None, None
        snap = None
        for _ in range(n):
            snap = self.ring.pop()
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
        if b.kind == "watch":
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
            if b.kind == "rung" and b.enabled:
                self.at_rung.setdefault(b.rung, b)
        self.data = any(b.kind != "rung" for b in self.items)

    def hits(self, pos: tuple[int, int] | None, ran: str) -> Stop | None:
        """Why to stop here (breakpoints, watches), or None."""
        hits = self.check_data(ran) if self.data else []
        if pos is not None and pos[1] == 0:
            b = self.at_rung.get(pos[0])
            if b is not None:
                b.hits += 1
                hits.insert(0, Stop(StopKind.BREAKPOINT, f"breakpoint #{b.id} at {b.text}"))
        if not hits:
            return None
        kind = StopKind.BREAKPOINT if any(h.kind == StopKind.BREAKPOINT for h in hits) \
            else StopKind.WATCH
        return Stop(kind, "; ".join(h.message for h in hits))

    def check_data(self, ran: str, commit: bool = True) -> list[Stop]:
        """Watches and conditions after a step or a scan: those that hit.
        With commit False only tell whether one would hit (no state changes)."""
        hits: list[Stop] = []
        for b in self.items:
            if b.kind == "rung" or b.test is None:
                continue
            try:
                v = b.test()
            except SoftPLCError:
                continue
            old = b.last
            if not commit:
                if b.enabled and (v != old if b.kind == "watch" or b.mode == "changes" else
                                  (bool(old) and not v) if b.mode == "falls" else
                                  (bool(v) and not old)):
                    return [Stop(StopKind.WATCH if b.kind == "watch" else
                                 StopKind.BREAKPOINT)]
                continue
            b.last = v
            if b.kind == "watch":
                if v != old:
                    self.changes.setdefault(b.text, deque(maxlen=HISTORY)).append(
                        Change(self.plc.scan_count, self.plc.time, ran, old, v))
                    if b.enabled:
                        b.hits += 1
                        hits.append(Stop(StopKind.WATCH, f"watch #{b.id} {b.text}: "
                                         f"{format_value(old)} -> {format_value(v)} "
                                         f"(in {ran})"))
            elif b.enabled:
                hit = (b.mode in ("", "rises") and v and not old) or \
                    (b.mode == "falls" and old and not v) or (b.mode == "changes" and v != old)
                if hit:
                    b.hits += 1
                    hits.append(Stop(StopKind.BREAKPOINT,
                                     f"breakpoint #{b.id} when {b.text} (in {ran})"))
        return hits
