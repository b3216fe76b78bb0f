"""The mutation fuzzers at full size, with a progress line (`make fuzz` runs it).

    .venv/bin/python tools/fuzz_mutations.py [--programs 4000] [--configs 1559]
        [--requirements 2000] [--symbols 2000] [--dxf 600] [--gcode 2000] [--api 400]

Programs: the ladder_programs/*.il texts mutated by `tests/test_il_recovery.mutate` (tokens
replaced, inserted, deleted, repeated); each either loads with its machine configuration
and devices and then runs 5 scans, or is refused with a SoftPLCError. Configs: the
ladder_programs/*.toml mutated by `tests/test_config_fuzz.mutated` (types, out-of-range
values, inf/nan, deleted and unknown keys); each loads, builds its devices and runs 5 scans,
or is a ConfigError / ProgramError. Requirement files, symbol CSVs, DXF drawings and G-code
programs (tests/input_fuzz.py: the shipped examples mutated with huge numbers, NaN, deep
nesting, binary bytes, cut short) are read or refused with their reader's coded error.
Online changes: mutated POST /api/program bodies (program, configuration and the JSON
itself) against the web monitor of the star-delta example, in this process (its server on
127.0.0.1): a 200 or a 4xx with a JSON error, never a 5xx. Any other exception while
loading is a *traceback*, any
exception out of a scan a *run-time crash* (a program fault is a HALT, not a crash). The
first few of each are printed with the input that caused them; the exit status is 1 if
there was any. The cases are new at every run (hypothesis, not derandomised).
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "tests" / "unit")]  # the seeds' modules

SHOWN = 3  # failures printed in full, per fuzzer


class Tally:
    """Outcomes of one fuzzer, and a progress line on stderr."""

    def __init__(self, name: str, total: int):
        self.name, self.total = name, total
        self.counts: Counter[str] = Counter()
        self.failures: list[str] = []
        self.t0 = time.monotonic()
        self._shown_at = 0.0

    @property
    def done(self) -> int:
        return sum(self.counts.values())

    def add(self, outcome: str, detail: str = "") -> None:
        self.counts[outcome] += 1
        if detail and len(self.failures) < SHOWN:
            self.failures.append(detail)
        now = time.monotonic()
        if now - self._shown_at > 0.5 or self.done == self.total:
            self._shown_at = now
            print(f"\r{self.line()}", end="", file=sys.stderr, flush=True)

    def line(self) -> str:
        parts = ", ".join(f"{n} {k}" for k, n in sorted(self.counts.items()))
        return (f"{self.name} {self.done}/{self.total} ({time.monotonic() - self.t0:.0f} s): "
                f"{parts}")

    @property
    def bad(self) -> int:
        return self.counts["tracebacks"] + self.counts["run-time crashes"]


def _refused(tally: Tally, e: Exception, what: str) -> None:
    if str(e).strip():
        tally.add("refused")
    else:
        tally.add("tracebacks", f"{what}\nrefused without a message: {type(e).__name__}")


def _scan(plc: Any, tally: Tally, what: str) -> None:
    try:
        plc.scan(5)
    except Exception:
        tally.add("run-time crashes", f"{what}\n{traceback.format_exc()}")
        return
    finally:
        plc.close()
    tally.add("ran")


def fuzz_programs(n: int) -> Tally:
    from hypothesis import strategies as st
    from test_il_recovery import CONFIGS, PROGRAMS, mutate

    from softplc import PLC
    from softplc.errors import SoftPLCError

    tally = Tally("mutated programs", n)

    def case(name: str, data: Any) -> None:
        text = mutate(PROGRAMS[name], data)
        config = ROOT / "ladder_programs" / CONFIGS[name]
        what = f"program {name} mutated:\n{text}"
        _load_and_scan(tally, what, lambda: PLC.from_source(text, config, file=name),
                       SoftPLCError)

    _run(case, n, st.sampled_from(sorted(PROGRAMS)), st.data())
    return tally


def _load_and_scan(tally: Tally, what: str, build: Any, refusals: Any) -> None:
    """Build a PLC: a clear refusal (`refusals`) is counted as such, anything else as a
    traceback; a PLC that loads runs its scans."""
    try:
        plc = build()
    except refusals as e:
        _refused(tally, e, what)
        return
    except Exception:
        tally.add("tracebacks", f"{what}\n{traceback.format_exc()}")
        return
    _scan(plc, tally, what)


def fuzz_configs(n: int) -> Tally:
    from test_config_fuzz import mutated

    from softplc import PLC
    from softplc.errors import ConfigError, ProgramError

    tally = Tally("mutated configs", n)

    def case(c: Any) -> None:
        path, cfg, program = c
        what = f"config {path.name} mutated: {cfg!r}"
        _load_and_scan(tally, what, lambda: PLC(program, cfg), (ConfigError, ProgramError))

    _run(case, n, mutated())
    return tally


def fuzz_reader(name: str, target: Callable[[Any], str], n: int) -> Tally:
    """A file reader's target of tests/input_fuzz.py: "read" or "refused", else a
    traceback."""
    from hypothesis import strategies as st

    tally = Tally(f"mutated {name}", n)

    def case(data: Any) -> None:
        try:
            tally.add(target(data))
        except Exception:
            tally.add("tracebacks", traceback.format_exc()[-3000:])

    _run(case, n, st.data())
    return tally


def fuzz_api(n: int) -> Tally:
    """Mutated online changes against the star-delta example's web monitor."""
    sys.path.insert(0, str(ROOT / "tests" / "e2e"))
    from input_fuzz import online_change
    from test_web_api import STAR, Stack

    stack = Stack(STAR, STAR.with_suffix(".toml"))
    try:
        return fuzz_reader("online changes", lambda data: online_change(
            stack.client().base, data), n)
    finally:
        stack.close()


def _run(case: Callable[..., None], n: int, *strategies: Any) -> None:
    """`case` on `n` generated examples: outcomes are tallied, never raised, so nothing is
    shrunk and the run is not cut short by the first failure."""
    from hypothesis import HealthCheck, Phase, given, settings

    run = settings(max_examples=n, deadline=None, database=None, phases=[Phase.generate],
                   suppress_health_check=list(HealthCheck))(given(*strategies)(case))
    run()


def main() -> int:
    ap = argparse.ArgumentParser(description="Run the program and config mutation fuzzers "
                                 "with a progress line; exit 1 on any traceback or crash.")
    ap.add_argument("--programs", type=int, default=4000, help="mutated programs (4000)")
    ap.add_argument("--configs", type=int, default=1559, help="mutated configs (1559)")
    from input_fuzz import TARGETS

    options = {"requirement files": "requirements", "symbol CSVs": "symbols",
               "DXF drawings": "dxf", "G-code programs": "gcode"}
    for name, (_target, full) in TARGETS.items():
        ap.add_argument(f"--{options[name]}", type=int, default=full,
                        help=f"mutated {name} ({full})")
    ap.add_argument("--api", type=int, default=400, help="mutated online changes (400)")
    args = ap.parse_args()
    runs: list[tuple[Callable[[], Tally], int]] = [
        (lambda: fuzz_programs(args.programs), args.programs),
        (lambda: fuzz_configs(args.configs), args.configs)]
    for name, (target, _full) in TARGETS.items():
        n = getattr(args, options[name])
        runs.append((lambda name=name, target=target, n=n: fuzz_reader(name, target, n), n))
    runs.append((lambda: fuzz_api(args.api), args.api))
    tallies = []
    for fuzz, n in runs:
        if n > 0:
            tallies.append(fuzz())
            print(file=sys.stderr)
    for t in tallies:
        print(t.line())
        for f in t.failures:
            print(f"--- {t.name}: {f}")
    bad = sum(t.bad for t in tallies)
    print(f"{bad} tracebacks or run-time crashes")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
