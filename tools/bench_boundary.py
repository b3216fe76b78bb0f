"""The daemon's work around each scan: the Modbus image's boundary (`take_snapshot` after
every scan, `apply_writes` before it) on the drawing table, as `softplc run` wires it.

Figures, in microseconds of CPU of the measuring thread (`time.thread_time`: steady on a
shared machine), best of `--repeat` timings:
  * one boundary of the drawing table's image (3,000 %MW, 256 %M) with nothing changed
    since the last one, with one %MW changed, with one %M changed, and with a retained-
    state store (`--state`: a commit and the blocks' JSON at every boundary);
  * the drawing table at `--speed max` (program, simulated table, trace), segments written
    by a host through the image as over Modbus: CPU per scan with the daemon's two hooks
    and without them (the host then writes the memory directly), and their difference,
    the per-scan overhead around the program.

`--against REV` runs the same figures for a git revision (e.g. main) or a checkout path and
this checkout alternately, each run in its own process (tools/bench_cpu_ab.py).

    .venv/bin/python tools/bench_boundary.py [--segments 6] [--repeat 5] [--against main]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

import bench_cpu_ab as ab
from bench_drawing import figure

from softplc import PLC
from softplc.modbus import ModbusImage
from softplc.persist import retain

ROOT = Path(__file__).resolve().parent.parent
PROGRAM = Path("ladder_programs/drawing_table.il")
CONFIG = Path("ladder_programs/drawing_table.toml")
BOUNDARIES = 2000  # boundaries per timing
SEGMENT_TIMEOUT_S = 120  # PLC seconds a segment may take (bench_drawing's)
HOST_REQUEST = 120  # INICIO > 100 asks for the segment (drawing_table.toml's symbols)


def _plc(root: Path, devices: bool = True) -> PLC:
    cfg = tomllib.loads((root / CONFIG).read_text())
    return PLC.from_file(root / PROGRAM, cfg, devices=devices)


def _best(fn: Callable[[], None], number: int, repeat: int) -> float:
    """Best us of thread CPU per call of `fn` over `repeat` timings of `number` calls."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time()
        for _ in range(number):
            fn()
        best = min(best, time.thread_time() - t0)
    return best / number * 1e6


def boundary(root: Path, repeat: int, number: int = BOUNDARIES) -> dict[str, float]:
    """us per boundary of the drawing table's image in four cases."""
    plc = _plc(root, devices=False)
    plc.scan(10)
    mem = plc.mem
    img = ModbusImage(mem)
    res = {"boundary_unchanged_us": _best(img.take_snapshot, number, repeat)}
    w = mem.mw.w

    def word() -> None:
        w[100] = (w[100] + 1) & 0x7FFF
        img.take_snapshot()

    def bit() -> None:
        mem.m[100] = not mem.m[100]
        img.take_snapshot()

    res["boundary_word_us"] = _best(word, number, repeat)
    res["boundary_bit_us"] = _best(bit, number, repeat)
    with tempfile.TemporaryDirectory() as tmp:
        store = retain.StateStore.open(Path(tmp) / "plc.state")
        store.load()
        store.start(retain.capture(mem))
        kept = ModbusImage(mem, store=store,
                           blocks=lambda: retain.encode_blocks(retain.capture_blocks(mem)))
        res["boundary_state_us"] = _best(kept.take_snapshot, number, repeat)
        store.close()
    return res


def drawing(root: Path, segments: int, hooks: bool) -> tuple[float, int]:
    """CPU s and scans of drawing `segments` segments at --speed max (homing excluded)."""
    plc = _plc(root)
    if hooks:  # as the daemon wires them
        img = ModbusImage(plc.mem)
        plc.before_scan.append(img.apply_writes)
        plc.after_scan.append(img.take_snapshot)

        def write(x: int, z: int, pen: int) -> None:
            img.write_words(0, [x, z])
            img.write_words(5, [pen])
            img.write_words(3, [HOST_REQUEST])
    else:
        def write(x: int, z: int, pen: int) -> None:
            plc["%MW0"], plc["%MW1"], plc["%MW5"], plc["%MW3"] = x, z, pen, HOST_REQUEST
    plc.run(0.01)
    if not plc.run_until(lambda p: p["%MW10"] == 0 and p.scan_count > 5, SEGMENT_TIMEOUT_S):
        raise RuntimeError("homing did not finish")
    scans0, t0 = plc.scan_count, time.thread_time()
    for i, (x, z, pen) in enumerate(figure(segments)):
        write(x, z, pen)
        plc.scan()  # the request reaches the program at the next scan start
        if not plc.run_until(lambda p: p["%MW3"] == 0 and p["%MW10"] == 0, SEGMENT_TIMEOUT_S):
            raise RuntimeError(f"segment {i} did not finish")
    return time.thread_time() - t0, plc.scan_count - scans0


def figures(root: Path, segments: int, repeat: int,
            number: int = BOUNDARIES) -> dict[str, float]:
    res = boundary(root, repeat, number)
    best: dict[bool, float] = {}
    for _ in range(repeat):
        for hooks in (False, True):  # alternating: a burst of load hits both alike
            cpu, scans = drawing(root, segments, hooks)
            best[hooks] = min(best.get(hooks, float("inf")), cpu / scans * 1e6)
            res["scans"] = scans
    res["scan_bare_us"], res["scan_daemon_us"] = best[False], best[True]
    res["overhead_us"] = best[True] - best[False]
    return res


KEYS: tuple[ab.Key, ...] = (
    ("boundary_unchanged_us", "boundary, nothing changed, us", False),
    ("boundary_word_us", "boundary, one %MW changed, us", False),
    ("boundary_bit_us", "boundary, one %M changed, us", False),
    ("boundary_state_us", "boundary with --state, us", False),
    ("scan_bare_us", "drawing scan, no hooks, us", False),
    ("scan_daemon_us", "drawing scan, daemon's hooks, us", False),
    ("overhead_us", "overhead per scan, us", False))


def report(r: dict[str, float]) -> str:
    return "\n".join(
        ["Scan boundary of the drawing table's image (us of CPU, best of the timings):"]
        + [f"  {label:36} {r[key]:8.2f}" for key, label, _ in KEYS]
        + [f"  ({r['scans']:.0f} scans a drawing run)"])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--segments", type=ab.positive, default=6,
                    help="segments drawn per timing (default 6)")
    ap.add_argument("--repeat", type=ab.positive, default=5,
                    help="timings per figure (default 5)")
    ab.add_against(ap, rounds=3)
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--root", type=Path, default=ROOT, help=argparse.SUPPRESS)  # (--against)
    a = ap.parse_args(argv)
    if a.against:
        print(ab.compare(a.against, a.rounds, ab.script_run(
            __file__, ["--segments", str(a.segments), "--repeat", str(a.repeat), "--json",
                       "--root", "{root}"]), KEYS, "Scan boundary A/B"))
        return 0
    r = figures(a.root, a.segments, a.repeat)
    print(json.dumps(r) if a.json else report(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
