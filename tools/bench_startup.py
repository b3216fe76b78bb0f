"""The `softplc` command's start-up: CPU seconds of a whole `python -m softplc ...` process
(user + system, from its rusage), best of N runs, for command lines that end soon after
their start (a help, a check, a REPL told to quit, a refusal), and `softplc run` of a
two-line program up to its banner's last line (then stopped with SIGTERM: its shutdown is
counted too).

    .venv/bin/python tools/bench_startup.py [--runs 5] [--json FILE]

CPU time, not wall time: other processes on the machine move it little. Every run loads
the compiled modules (`__pycache__`): PYTHONDONTWRITEBYTECODE is removed from the
children's environment, and a first run, not counted, writes them if they are missing.
What a command imports before its work is where a change shows (`python -X importtime -m
softplc ...` says which modules).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from peers.common import print_report, progress

ROOT = Path(__file__).resolve().parents[1]
PROGRAM = "tests/debug_sample.il"  # 9 rungs, a timer: the debugger's sample
CONFIG = "tests/debug_sample.toml"
PLANT = "ladder_programs/plant/plant.toml"
# a machine's configuration: steppers, limit switches, a pen and a trace
MACHINE, MACHINE_CONFIG = "ladder_programs/drawing_table.il", "ladder_programs/drawing_table.toml"
# a program with no configuration (no devices): what `softplc run` costs before its work
TINY = ("tiny.il", "LD %I0.0\nST %Q0.0\n")
# the daemon's last banner line (softplc/daemon.py `_banner`: tools and tests wait for it)
BANNER_END = "Modbus TCP server listening on "
# (label, the command line after `python -m softplc`[, the output line that ends the
# run: the process is then stopped]); {tmp}: a fresh folder holding TINY
Command = tuple[str, tuple[str, ...]] | tuple[str, tuple[str, ...], str]
COMMANDS: tuple[Command, ...] = (
    ("python -c pass (the interpreter alone)", ()),
    ("softplc --help (every command's parser)", ("--help",)),
    ("softplc run --help", ("run", "--help")),
    ("softplc check PROGRAM", ("check", PROGRAM, "--config", CONFIG)),
    ("softplc check drawing table (devices)", ("check", MACHINE, "--config", MACHINE_CONFIG)),
    ("softplc run tiny.il, to its banner", ("run", "{tmp}/" + TINY[0], "--port", "0",
                                            "--web", "off"), BANNER_END),
    ("softplc repl PROGRAM -x quit", ("repl", PROGRAM, "--config", CONFIG, "-x", "quit")),
    ("softplc plant check plant.toml", ("plant", "check", PLANT)),
    ("softplc plant down (nothing up)", ("plant", "down", PLANT, "--state-dir", "{tmp}")),
    ("softplc fleet, ports refused", ("fleet", PROGRAM, "--count", "2", "--ports",
                                      "5100,5100")),
)
DEFAULT_RUNS = 5


def cpu_of(argv: list[str], cwd: Path, until: str | None = None) -> float:
    """User + system CPU seconds of one run of `argv` (its exit status not looked at: a
    refusal is a start-up too). With `until`, the process is stopped (SIGTERM) once it
    has printed a line starting with it; RuntimeError if it ends before."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL if until is None else subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    if until is not None:
        assert proc.stdout is not None
        if not any(line.startswith(until) for line in proc.stdout):
            proc.wait()
            raise RuntimeError(f"{' '.join(argv)} ended without printing {until!r}")
        proc.send_signal(signal.SIGTERM)
        proc.stdout.read()  # its shutdown lines: a full pipe must not block it
        proc.stdout.close()
    _, _, usage = os.wait4(proc.pid, 0)
    proc.returncode = 0  # reaped here: Popen must not wait for it again
    return usage.ru_utime + usage.ru_stime


def run(runs: int = DEFAULT_RUNS,
        commands: tuple[Command, ...] = COMMANDS) -> dict[str, Any]:
    """{label: {"best_s", "median_s", "argv"}} over `runs` runs of each command line."""
    if runs < 1:
        raise ValueError("runs must be >= 1")
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="bench_startup_") as tmp:
        Path(tmp, TINY[0]).write_text(TINY[1])
        for label, args, *until in commands:
            words = [a.format(tmp=tmp) for a in args]
            argv = [sys.executable, *(["-m", "softplc", *words] if words else ["-c", "pass"])]
            stop = until[0] if until else None
            progress(f"start-up: {label}")
            cpu_of(argv, ROOT, stop)  # writes what __pycache__ lacks; not counted
            times = sorted(cpu_of(argv, ROOT, stop) for _ in range(runs))
            out[label] = {"best_s": times[0], "median_s": times[len(times) // 2],
                          "argv": words}
    return out


def report(res: dict[str, Any]) -> str:
    w = max(len(k) for k in res)
    lines = ["softplc start-up: CPU s of the whole process (user + system), best / median",
             f"  {'command':{w}} {'best':>6} {'median':>7}"]
    for label, r in res.items():
        lines.append(f"  {label:{w}} {r['best_s']:6.3f} {r['median_s']:7.3f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=DEFAULT_RUNS,
                    help=f"runs per command line, the best kept (default {DEFAULT_RUNS})")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON here")
    a = ap.parse_args(argv)
    if a.runs < 1:
        ap.error("--runs must be >= 1")
    res = run(a.runs)
    print_report(report(res), res, a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
