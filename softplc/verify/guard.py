"""A requirement checked in a child process, so that its time is a hard bound and a solver
crash is an answer, not the end of the run.

The child is forked: it inherits the model already built. It runs `engines.requirement`,
whose clock ends it, UNKNOWN, at its time. The parent waits that time plus `MARGIN_S`; a
child still running then (a z3 call overran its timeout: bit-blasting a product does not
look at it) is killed with its process group (its Spacer child too) and the requirement is
UNKNOWN, naming what it last reported. A child that dies without an answer (z3 aborts or
segfaults at its memory cap: seen on loops of input-dependent products) is UNKNOWN with
the signal and z3's last words. Where `os.fork` does not exist, it runs in this process.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from softplc.verify.defaults import MARGIN_S
from softplc.verify.engines import FOUND, Limits, Progress, Result, requirement
from softplc.verify.stateinv import PROVE_S, prove

TRACE_S = 120.0  # s it waits for a counterexample's trace (concrete scans) once found


def check(model: Any, spec: Any, req: Any, lemmas: list[Any], limits: Limits,
          watch: list[str], progress: Progress | None = None) -> Result:
    """`engines.requirement` in a child process (see the module's docstring); the model's
    own facts (`stateinv.prove`) proven first, once, and inherited by every child."""
    facts(model, limits)

    def work(report: Progress | None) -> Result:
        return requirement(model, spec, req, lemmas, limits, watch, report)
    return isolated(work, limits.seconds, progress)


def facts(model: Any, limits: Limits) -> list[Any]:
    """The model's own facts (`stateinv.prove`), proven once in a child within a
    requirement's time at most, kept on the model for every requirement after."""
    return prove(model, isolated, min(PROVE_S, limits.seconds))


def isolated(work: Callable[[Progress | None], Result], seconds: float,
             progress: Progress | None = None) -> Result:
    """`work(progress)` in a forked child, ended `seconds` + MARGIN_S from now at the
    latest; its exceptions other than a solver's are raised here (a bug is a bug)."""
    if not hasattr(os, "fork"):  # pragma: no cover - not on Linux
        return work(progress)
    for f in (sys.stdout, sys.stderr):  # the child must not write their buffers again
        f.flush()
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    # the child's temporary files (Spacer's clauses) and stderr: removed when it is killed
    with tempfile.TemporaryDirectory(prefix="softplc-verify-") as tmp, \
            open(os.path.join(tmp, "stderr"), "w+b") as err:
        proc = ctx.Process(target=_child, args=(work, send, err.fileno(), tmp), daemon=True)
        t0 = time.monotonic()
        proc.start()
        send.close()
        _own_group(proc.pid)
        last = ["before any progress (its cone of influence, the first scans' terms)"]
        try:
            msg = _wait(recv, t0 + seconds + MARGIN_S, progress, last)
        finally:
            _kill(proc)
            recv.close()
        if msg is None:
            return Result("UNKNOWN", "", 0, time.monotonic() - t0, note=(
                f"the solver did not stop at the requirement's {seconds:g} s ({last[0]}): "
                f"its process was killed {MARGIN_S:g} s later"))
        if msg[0] == "result":
            return msg[1]
        if msg[0] == "error":
            raise RuntimeError(f"softplc verify: the requirement's process failed:\n{msg[1]}")
        err.seek(0)
        words = err.read().decode(errors="replace").strip().splitlines()
    how = _signal_name(proc.exitcode)
    return Result("UNKNOWN", "", 0, time.monotonic() - t0, note=(
        f"the solver's process ended without an answer ({how}) {last[0]}"
        + (f"; z3 said: {words[-1][:200]}" if words else "")
        + f": it may have reached its memory cap ({_memory_cap()}; SOFTPLC_Z3_MEMORY_MB)"))


def _wait(recv: Connection, end: float, progress: Progress | None,
          last: list[str]) -> tuple[Any, ...] | None:
    """The child's last message ("result" or "error"; ("crashed",) when it died without
    one), passing its progress on; None when `end` came first."""
    while True:
        left = end - time.monotonic()
        if left <= 0:
            return None
        if not recv.poll(left):
            continue
        try:
            msg = recv.recv()
        except EOFError:  # the child died: no answer
            return ("crashed",)
        if msg[0] != "progress":
            return msg
        engine, depth, secs = msg[1:]
        last[0] = f"after {engine} reached depth {depth}"
        if engine == FOUND:  # the solver's part is done: the trace is concrete scans
            end = max(end, time.monotonic() + TRACE_S)
            last[0] = f"building the trace of a counterexample of {depth} scans"
        if progress:
            progress(engine, depth, secs)


def _child(work: Callable[[Progress | None], Result], send: Connection, err: int,
           tmp: str) -> None:
    os.setpgid(0, 0)  # its own group: killed with what it starts (Spacer)
    os.dup2(err, 2)  # what z3 prints before it aborts, for the parent's message
    tempfile.tempdir = tmp
    import z3

    def report(engine: str, depth: int, secs: float) -> None:
        send.send(("progress", engine, depth, secs))
    t0 = time.monotonic()
    try:
        res = work(report)
    except z3.Z3Exception as e:  # the solver failed (its memory cap...): an answer too
        why = e.value.decode(errors="replace") if isinstance(e.value, bytes) else str(e)
        res = Result("UNKNOWN", "", 0, time.monotonic() - t0, note=(
            f"the solver failed ({why}; its memory cap: {_memory_cap()}, "
            "SOFTPLC_Z3_MEMORY_MB)"))
    except BaseException:  # noqa: BLE001 - a bug: the parent raises it
        send.send(("error", traceback.format_exc()))
        return
    send.send(("result", res))


def _own_group(pid: int | None) -> None:
    """The child's process group is its own (set on both sides: whichever runs first)."""
    try:
        os.setpgid(pid or 0, pid or 0)
    except OSError:  # already set by the child, or it has ended
        pass


def _kill(proc: multiprocessing.Process) -> None:
    """End the child and its process group (Spacer), then reap it."""
    if proc.pid is not None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:  # no such group: the child ended with no other process in it
            pass
    if proc.is_alive():  # (its group not made yet: killed by its id)
        proc.kill()
    proc.join()


def _signal_name(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return signal.Signals(-code).name
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"


def _memory_cap() -> str:
    import z3
    try:
        return f"{int(z3.get_param('memory_max_size'))} MB"
    except (z3.Z3Exception, ValueError):
        return "unset"
