"""A/B runs of a benchmark: two versions of softplc, each side a git revision of this
repository (exported to a temporary directory) or the path of a checkout.

Each run is a child process importing softplc from its side's tree; the runs alternate
(A B, B A, A B, ...) so a burst of load from elsewhere hits both sides alike and neither
always runs first; the figures are CPU time of the timing thread (`time.thread_time`,
blind to the time other processes hold the core). The table gives each figure's best /
median over the rounds and the ratio of the bests (> 1: B is better). Benchmarks reach
it through `--against` (tools/bench_engine.py, tools/bench_cutting.py) or call it
themselves (tools/bench_sim_ab.py); alone, it compares `plc.scan()` of the 40-rung mixed
program and three ladder_programs examples (without devices), in us of CPU per scan:

    .venv/bin/python tools/bench_cpu_ab.py A [B] [--rounds 3] [--scans 5000]

A and B: a revision (main, HEAD~1, e166929) or a checkout directory; B defaults to this
checkout. Both run from copies in one temporary folder (a revision exported by git
archive, a checkout's files as they are), so neither side runs from a different place.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
THIS = "this checkout"

# (key of a child's JSON figures, label, higher is better)
Key = tuple[str, str, bool]
Run = Callable[["Side"], dict[str, Any]]


class ABError(SystemExit):
    """A side that is neither a checkout nor a revision, or a run that failed: its message
    reaches the user without a traceback (a SystemExit), and tests can catch it."""


@dataclass(frozen=True)
class Side:
    label: str  # what the table calls it: the revision as given (+ its commit) or the path
    root: Path  # a copy of its tree, holding softplc/


def _git(*args: str, repo: Path = ROOT) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, check=False)


def _export(rev: str, into: Path) -> Side:
    """`rev` of this repository as a plain tree (git archive) under `into`."""
    found = _git("rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}")
    if found.returncode:
        raise ABError(f"{rev!r}: neither a checkout directory nor a git revision of {ROOT}")
    commit = found.stdout.decode().strip()
    arch = _git("archive", "--format=tar", commit)
    if arch.returncode:
        raise ABError(f"git archive {rev}: {arch.stderr.decode(errors='replace').strip()}")
    into.mkdir(parents=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=arch.stdout, check=True)
    label = rev if commit.startswith(rev) else f"{rev} ({commit[:7]})"
    return Side(label, into)


def _copy(checkout: Path, into: Path) -> None:
    """The files of a checkout as they are (uncommitted changes and new files git does not
    ignore included) into `into`: every side then runs from the same temporary folder,
    under a path of the same length. (Run from /work/h-ab, star_delta.il's scan measured
    3-5 % slower than the same code exported under /tmp: three A/B runs of 5-6 rounds,
    whichever side it was.)"""
    listed = _git("ls-files", "-z", "--cached", "--others", "--exclude-standard",
                  repo=checkout)
    if listed.returncode:  # not a git checkout: all but caches and environments
        shutil.copytree(checkout, into, ignore=shutil.ignore_patterns(
            ".git", ".venv", "venv", "__pycache__", "*.pyc", ".*_cache"))
        return
    for name in filter(None, listed.stdout.decode().split("\0")):
        src = checkout / name
        if src.is_file():  # (a tracked file deleted in the working tree is left out)
            (into / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, into / name)
            _copy_bytecode(src, into / name)


def _copy_bytecode(src: Path, dst: Path) -> None:
    """The compiled module of source `src` (git-ignored) beside its copy `dst`: the side's
    first child then loads it instead of compiling every module again (0.6 s of CPU for
    softplc.plc). Python checks it against the copy as against the original (copy2 keeps
    the source's size and mtime; a stale one is compiled again) and names the copy in
    the code's file names."""
    if src.suffix != ".py" or sys.implementation.cache_tag is None:
        return
    pyc = src.parent / "__pycache__" / f"{src.stem}.{sys.implementation.cache_tag}.pyc"
    if pyc.is_file():
        (dst.parent / "__pycache__").mkdir(exist_ok=True)
        shutil.copy2(pyc, dst.parent / "__pycache__" / pyc.name)


def resolve(spec: str, tmp: Path) -> Side:
    """A side from a checkout path (a directory holding softplc/; its files copied) or a
    git revision of this repository (exported), under `tmp`; a directory wins over a
    revision of the same name."""
    path = Path(spec).expanduser()
    into = tmp / f"side{len(list(tmp.iterdir()))}"
    if not path.is_dir():
        return _export(spec, into)
    if not (path / "softplc" / "__init__.py").is_file():
        raise ABError(f"{spec}: a directory without softplc/, not a checkout")
    _copy(path.resolve(), into)
    return Side(THIS if path.resolve() == ROOT else spec, into)


@contextmanager
def sides(specs: Sequence[str]) -> Iterator[list[Side]]:
    """The sides named by `specs`, revisions exported and checkouts copied for the
    duration of the block."""
    with tempfile.TemporaryDirectory(prefix="bench_ab_") as tmp:
        yield [resolve(s, Path(tmp)) for s in specs]


def child(side: Side, argv: Sequence[str]) -> dict[str, Any]:
    """`python argv` in a process importing softplc from the side's tree (PYTHONPATH, and
    its working directory): the JSON object its last line of output prints."""
    env = dict(os.environ, PYTHONPATH=str(side.root))
    out = subprocess.run([sys.executable, *argv], capture_output=True, text=True, env=env,
                         cwd=side.root, check=False)
    if out.returncode:
        raise ABError(f"{side.label}: the benchmark failed:\n{out.stderr[-2000:]}")
    try:
        res = json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        res = None
    if not isinstance(res, dict):
        raise ABError(f"{side.label}: the benchmark printed no JSON object on its last line:\n"
                      f"{out.stdout[-500:]}")
    return res


def _check_rounds(rounds: int) -> None:
    if rounds < 1:
        raise ABError("--rounds must be >= 1")


def alternate(sides: Sequence[Side], rounds: int, run: Run,
              what: str = "A/B") -> list[list[dict[str, Any]]]:
    """`run(side)` `rounds` times for each side, alternating, every other round in the
    reverse order (A B, B A, A B, ...: neither side always runs first); progress and an
    ETA on stderr. The results per side, in the order of `sides`."""
    _check_rounds(rounds)
    runs: list[list[dict[str, Any]]] = [[] for _ in sides]
    total, t0 = rounds * len(sides), time.monotonic()
    for i in range(rounds):
        order = list(enumerate(sides))
        for j, (n, side) in enumerate(order[::-1] if i % 2 else order):
            done = i * len(sides) + j
            eta = f", ETA {(time.monotonic() - t0) / done * (total - done):.0f} s" if done else ""
            print(f"[bench] {what} run {done + 1}/{total} (round {i + 1}/{rounds}): "
                  f"{side.label}{eta}", file=sys.stderr, flush=True)
            runs[n].append(run(side))
    return runs


def table(sides: Sequence[Side], runs: Sequence[Sequence[dict[str, Any]]],
          keys: Sequence[Key], title: str) -> str:
    """Each key's best / median per side and the ratio of the bests, B over A for a
    figure where higher is better, A over B otherwise (> 1: B is better)."""
    a, b = (s.label for s in sides)
    w = max(30, *(len(k[1]) for k in keys))
    lines = [f"{title}, {len(runs[0])} alternating runs each",
             f"  A: {a}; B: {b}; load average {os.getloadavg()[0]:.1f} at the end",
             f"  {'figure':{w}} {'A best / median':>19} {'B best / median':>19} {'B vs A':>7}"]
    for key, label, higher in keys:
        cells, best = [], []
        for side_runs in runs:
            vals = [r[key] for r in side_runs if key in r]
            if not vals:
                cells.append(f"{'-':>19}")
                continue
            best.append(max(vals) if higher else min(vals))
            cells.append(f"{best[-1]:8.2f} / {statistics.median(vals):8.2f}")
        ratio = "-"
        if len(best) == 2 and min(best) > 0:
            ratio = f"{best[1] / best[0] if higher else best[0] / best[1]:.3f}x"
        lines.append(f"  {label:{w}} {cells[0]:>19} {cells[1]:>19} {ratio:>7}")
    return "\n".join(lines)


def compare(a: str, rounds: int, run: Run, keys: Sequence[Key], title: str,
            b: str = str(ROOT)) -> str:
    """The whole A/B: resolve both sides (B: this checkout by default), run them
    alternating, the table. A bad --rounds is refused before the sides are made (a
    checkout's copy, a revision's export)."""
    _check_rounds(rounds)
    with sides([a, b]) as both:
        return table(both, alternate(both, rounds, run), keys, title)


def script_run(script: str, args: Sequence[str]) -> Run:
    """A run of a benchmark script of this checkout (the same code measuring each side)
    against the side's softplc; `{root}` in `args` becomes the side's tree."""
    return lambda side: child(side, [script, *(x.format(root=side.root) for x in args)])


# The standalone figure: plc.scan() in CPU time, programs of the side's tree.
SCAN_CHILD = r"""
import json, sys, time, timeit
root, scans = sys.argv[1], int(sys.argv[2])
sys.path[:0] = [root, root + "/tools"]
from softplc.plc import PLC
from peers.programs import mixed_program
res = {}
def t(name, plc):
    plc.scan(100)
    best = min(timeit.repeat(plc.scan, number=scans, repeat=5, timer=time.thread_time))
    res[name] = best / scans * 1e6
src, cfg = mixed_program()
t("mixed", PLC.from_source(src, cfg))
for name in ("drawing_table", "traffic_light", "star_delta"):
    lp = root + "/ladder_programs/" + name
    t(name, PLC.from_file(lp + ".il", lp + ".toml", devices=False))
print(json.dumps(res))
"""
SCAN_KEYS: tuple[Key, ...] = (
    ("mixed", "mixed program (40 rungs), us", False),
    ("drawing_table", "drawing_table.il, us", False),
    ("traffic_light", "traffic_light.il, us", False),
    ("star_delta", "star_delta.il, us", False))


def positive(text: str) -> int:
    """argparse type: a whole number >= 1 (rounds, scans)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{n} must be >= 1")
    return n


def add_against(ap: argparse.ArgumentParser, rounds: int, note: str = "") -> None:
    """The --against REV and --rounds N options of a benchmark that can A/B itself."""
    ap.add_argument("--against", metavar="REV",
                    help="A/B: also run a git revision (e.g. main) or a checkout path, "
                         f"alternating{note}")
    ap.add_argument("--rounds", type=positive, default=rounds,
                    help=f"runs per side with --against (default {rounds})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="A/B of plc.scan() cost in CPU time; each side a git revision or a "
                    "checkout path (see the module docstring for --against elsewhere).")
    ap.add_argument("a", help="side A: revision (e.g. main, HEAD~1) or checkout path")
    ap.add_argument("b", nargs="?", default=str(ROOT),
                    help="side B (default: this checkout)")
    ap.add_argument("--rounds", type=positive, default=3, help="runs per side (default 3)")
    ap.add_argument("--scans", type=positive, default=5000,
                    help="scans per timing (default 5000)")
    args = ap.parse_args(argv)
    run = lambda side: child(side, ["-c", SCAN_CHILD, str(side.root), str(args.scans)])  # noqa: E731
    print(compare(args.a, args.rounds, run, SCAN_KEYS,
                  "plc.scan() A/B, CPU us per scan (best of 5 timings a run)", args.b))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
