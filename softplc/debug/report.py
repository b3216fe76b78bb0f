"""The stepper's results as the REPL shows them: every text of a run (why it stopped,
the hits, the PLC's state, where it stands) is built here, from the typed data of
`stepper.py`, which builds none."""

from __future__ import annotations

from softplc.debug.stepper import CondHit, Executed, Hit, Position, Ran, Reloaded, RungHit, StopKind
from softplc.il import ast as A
from softplc.il.printer import format_instruction
from softplc.twido.display import format_value


def executed_text(e: Executed) -> str:
    """What a step ran: "scan start", "rung 3 instr 2" (+ " + scan end"), "scan"."""
    if e.fast:
        return "scan"
    if e.rung is None:
        return "scan start"
    return f"rung {e.rung} instr {e.k}" + (" + scan end" if e.scan_end else "")


def hit_text(h: Hit) -> str:
    if isinstance(h, RungHit):
        return f"breakpoint #{h.id} at {h.text}"
    if isinstance(h, CondHit):
        return f"breakpoint #{h.id} when {h.text} (in {executed_text(h.where)})"
    return (f"watch #{h.id} {h.text}: {format_value(h.old)} -> {format_value(h.new)} "
            f"(in {executed_text(h.where)})")


def position_text(pos: Position, program: A.Program) -> str:
    """`[scan 12, t = 0.120 s] before rung 3 (title) instr 0: LD %I0.0`, or at the scan
    boundary."""
    t = f"scan {pos.scan}, t = {pos.time:.3f} s"
    if pos.rung is None or pos.k is None:
        return f"[{t}] at the scan boundary"
    rung = program.rungs[pos.rung]
    ins = rung.instructions[pos.k] if pos.k < len(rung.instructions) else None
    text = format_instruction(ins) if ins is not None else ""
    title = f" ({rung.title})" if rung.title else ""
    return f"[{t}] before rung {pos.rung}{title} instr {pos.k}: {text}"


def run_text(ran: Ran, program: A.Program, limit: int = 0) -> str:
    """A run's result: why it stopped (the hits, an interrupt, the end of a scan, no hit
    in `limit` scans), the PLC's state when it is not running, then the position."""
    lines = []
    if ran.hits:
        lines.append("; ".join(hit_text(h) for h in ran.hits))
    elif ran.reason == StopKind.INTERRUPTED:
        lines.append("interrupted")
    elif ran.reason == StopKind.SCAN_END:
        lines.append(f"scan {ran.position.scan} complete")
    elif ran.reason == StopKind.SCAN_LIMIT:
        lines.append(f"no breakpoint hit in {limit} scans")
    if not ran.running:
        lines.append(f"PLC in {ran.state}" + (f": {ran.fault}" if ran.fault else ""))
    lines.append(position_text(ran.position, program))
    return "\n".join(lines)


def reload_text(done: Reloaded) -> list[str]:
    """The rung breakpoints a reload disabled, one line each."""
    return [f"breakpoint #{b.id} ({b.key}) disabled: no such rung now" for b in done.disabled]
