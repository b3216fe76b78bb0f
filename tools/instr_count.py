"""Instruction counts under valgrind's callgrind: benchmark figures that do not move with
the machine or its load (issue 32 item 6). Two machines of the same kind timed the same
code 1.5-1.8x apart; the count of x86 instructions it executes is the same on both.

`count(child, n_small, n_large)` runs `python -c CHILD N` under
`valgrind --tool=callgrind --instr-atstart=no` twice, the child's measured loop run
N = n_small then n_large times. The child calls `start()` before its loop, which turns
the instrumentation on (`callgrind_control -i on`): the start-up, imports and set-up run
uninstrumented (several times faster). The difference of the two totals over
(n_large - n_small) is the count per iteration, without what both runs share (the
switch itself, the loop's first and last steps). The clock calls (`clock_gettime` and
what it calls, e.g. under the statistics' `time.perf_counter`) are counted apart: their
inclusive cost from `callgrind_annotate`, differenced the same way, so a change in how
often the engine reads the clock shows as such. PYTHONHASHSEED is fixed so that two runs of the same
code execute the same instructions.

Where valgrind is missing (`available()` False) the benchmarks say so and skip the
count; `apt-get install -y valgrind` provides it.
"""

from __future__ import annotations

import os
import sys

# Each measured child imports this module to call start(), uninstrumented but under
# valgrind (several times slower than plain), and starts without `site` (`_run`): only
# os and sys at the top; re, pathlib, subprocess, shutil and tempfile, a quarter to half
# a second of CPU each per child there, where the parent's side uses them.

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VALGRIND = "valgrind"
ANNOTATE = "callgrind_annotate"
CONTROL = "callgrind_control"
HASH_SEED = "0"  # the same dict and set orders in every run
UNDER = "SOFTPLC_CALLGRIND"  # set in the child's environment by `_run`
# Functions whose inclusive cost is "the clock" (glibc's entry point and its vDSO or
# syscall path below it; the largest inclusive figure is the outermost, all of them).
CLOCK_FUNC = r"clock_gettime"
_TOTAL = r"^(?:summary|totals):\s*(\d+)"  # (multi-line)
_ANNOTATED = r"^\s*([\d,]+)\s+\([^)]*\)\s+(\S+)"
MISSING = "instruction count skipped: valgrind not found (apt-get install -y valgrind)"


class Count:
    """Instructions per iteration: `total` in all, of which `clock` in the clock calls."""

    __slots__ = ("total", "clock")

    def __init__(self, total: float, clock: float) -> None:
        self.total = total
        self.clock = clock

    def __repr__(self) -> str:
        return f"Count(total={self.total!r}, clock={self.clock!r})"

    @property
    def without_clock(self) -> float:
        return self.total - self.clock

    def line(self, what: str) -> str:
        return (f"{what}: {self.without_clock:,.0f} instructions (callgrind Ir), "
                f"+ {self.clock:,.0f} in clock calls")


def available() -> bool:
    import shutil

    return all(shutil.which(t) is not None for t in (VALGRIND, ANNOTATE, CONTROL))


def start() -> None:
    """In a child run by `count`: instrument from here on (elsewhere: nothing)."""
    if os.environ.get(UNDER):
        # valgrind switches instrumentation on while this process is blocked in one
        # waitpid(): the instructions counted after it are the same in every run. Waiting
        # with subprocess.run's communicate() loop would count a number of its iterations
        # that depends on the machine's load (a repeated run differed by 3 %).
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            pid = os.posix_spawnp(CONTROL, [CONTROL, "-i", "on", str(os.getpid())],
                                  os.environ, file_actions=[(os.POSIX_SPAWN_DUP2, null, 1),
                                                            (os.POSIX_SPAWN_DUP2, null, 2)])
        finally:
            os.close(null)
        _, status = os.waitpid(pid, 0)
        if code := os.waitstatus_to_exitcode(status):
            raise RuntimeError(f"{CONTROL} -i on: exit status {code}")


def _run(child: str, n: int, out: os.PathLike[str],
         args: tuple[str, ...]) -> tuple[int, int]:
    """(total Ir, inclusive Ir of the clock calls) of one run of the child.

    The child runs `python -S`: without `site`, whose .pth files (setuptools' editable
    finder imports pathlib, re and urllib.parse) cost about 0.5 s of CPU per run under
    valgrind; the site-packages folders are on its PYTHONPATH instead, after this
    repository and tools/ (the editable install's finder only pointed at ROOT)."""
    import re
    import site
    import subprocess

    path = [ROOT, os.path.join(ROOT, "tools"), *site.getsitepackages()]
    env = dict(os.environ, PYTHONHASHSEED=HASH_SEED, **{UNDER: "1"},
               PYTHONPATH=os.pathsep.join(path))
    cmd = [VALGRIND, "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}",
           sys.executable, "-S", "-c", child, str(n), *args]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env, check=False)
    if r.returncode:
        raise RuntimeError(f"callgrind run failed ({r.returncode}):\n{r.stderr[-2000:]}")
    with open(out, errors="replace") as f:
        m = re.search(_TOTAL, f.read(), re.M)
    if m is None:
        raise RuntimeError(f"no total in {out}")
    ann = subprocess.run([ANNOTATE, "--inclusive=yes", "--threshold=100", str(out)],
                         capture_output=True, text=True, check=False).stdout
    clock = [int(c.replace(",", "")) for c, fn in re.findall(_ANNOTATED, "\n".join(
        ln for ln in ann.splitlines() if re.search(CLOCK_FUNC, ln)))]
    return int(m.group(1)), max(clock, default=0)


def count(child: str, n_small: int, n_large: int, *args: str) -> Count:
    """Instructions per iteration of the child's loop (see the module's docstring); the
    child gets its loop count as argv[1], then `args`."""
    if not 0 <= n_small < n_large:
        raise ValueError("expected 0 <= n_small < n_large")
    # here, not at the top: every measured child imports this module to call start(), and
    # tempfile (with random, hashlib) is 0.6 s of CPU in a child's start-up under valgrind
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        a = _run(child, n_small, Path(tmp) / "small.out", args)
        b = _run(child, n_large, Path(tmp) / "large.out", args)
    n = n_large - n_small
    return Count(total=(b[0] - a[0]) / n, clock=(b[1] - a[1]) / n)
