"""The work of `softplc cut` (see cut.py, which parses the arguments)."""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from softplc.machines.cutting import (
    Arc,
    CuttingError,
    NewtonCurve,
    Piece,
    load_piece,
    piece_words,
    split_line,
)
from softplc.machines.cutting.geometry import Point
from softplc.machines.cutting.motion import simulate
from softplc.machines.cutting.piece import DWELL
from softplc.machines.cutting.preview import preview
from softplc.machines.cutting.regmap import FRAME_LEN, SEG_BASE
from softplc.machines.cutting.seed import run_trigger_chain, thesis_split

#: The operator's commands, given instead of a piece file (cut.py's help names them).
ACTIONS = ("reset", "home", "jog")


def _load(args: argparse.Namespace) -> Piece:
    return load_piece(args.piece, speed=args.speed, move_speed=args.move_speed,
                      accel=args.accel, tolerance=args.tolerance, work_area=args.work_area)


def _write_frames(piece: Piece, out: str) -> None:
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    try:
        with open(out, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["segment", "kind", "x_mm", "y_mm", "speed_mm_s", "where",
                        "x_um", "y_um", "kind_code", "seg_no",
                        *(f"MW{SEG_BASE + i}" for i in range(FRAME_LEN)),
                        "vx_mm_s", "vy_mm_s", "ax_mm_s2", "ay_mm_s2", "duration_s",
                        "dwell_s"])
            segs = piece.segments()
            for s, sw in zip(segs, piece_words(segs), strict=True):
                # what the PLC should compute for this segment (the corrected split)
                split = split_line(s.start, s.end, s.speed, piece.accel)
                w.writerow([s.number, s.kind, f"{s.end[0]:.6f}", f"{s.end[1]:.6f}",
                            f"{s.speed:g}", s.where, sw.x_um, sw.y_um, sw.kind, sw.number,
                            *sw.frame(),
                            *(f"{v:.9g}" for v in (split.x.speed, split.y.speed,
                                                   split.x.accel, split.y.accel,
                                                   split.duration)), f"{s.dwell:g}"])
    except OSError as e:
        raise CuttingError(f"cannot write {out}: {e.strerror or e}") from None


def _report_chain(piece: Piece) -> None:
    """The thesis sequences a piece as a trigger chain whose end tests are not gated (B19):
    say whether this piece would run once or repeat forever that way."""
    segs = piece.segments()
    run = run_trigger_chain([s.end for s in segs], piece.start, gated=False,
                            max_passes=4 * len(segs) + 10)
    if run.runs_forever:
        cycle = run.ops[-run.cycle_moves:]
        print(f"seed mode: the thesis's trigger chain (ungated end tests, B19) would repeat "
              f"segments {min(cycle)}-{max(cycle)} forever (cycle found after "
              f"{run.passes} passes)")
    elif run.finished:
        print("seed mode: the thesis's trigger chain runs this piece once")
    else:
        print(f"seed mode: the thesis's trigger chain did not end within {run.passes} "
              "passes")


def _report_simulation(piece: Piece, dt: float, seed: bool | str) -> None:
    runs = [("corrected", piece.segments(), split_line)]
    if seed:
        runs.append(("thesis (seed mode, equal accelerations)", piece.segments(seed=seed),
                     thesis_split))
    for name, segs, split in runs:
        samples = simulate(segs, piece.accel, dt, split)
        worst, at = _worst_deviation(piece, [(s.x, s.y) for s in samples if s.torch])
        print(f"simulated, {name}: {samples[-1].t if samples else 0:.3f} s of motion, "
              f"{len(samples)} samples (dt {dt:g} s); the torch-on path is at most "
              f"{worst:.6f} mm from the ideal shape (at {at[0]:.4f}, {at[1]:.4f}; chord "
              f"tolerance {piece.tolerance:g})")


def _worst_deviation(piece: Piece, points: list[Point]) -> tuple[float, Point]:
    """The largest `piece.deviation` of the points and the point (of equal deviations the
    largest (x, y), as max over (deviation, point) pairs), all points at once."""
    if not points:
        return 0.0, piece.start
    xy = np.array(points, float)
    dev = piece.deviations(xy[:, 0], xy[:, 1])
    worst = float(dev.max())
    return worst, max(p for p, d in zip(points, dev.tolist(), strict=True) if d == worst)


def _report_seed(piece: Piece, variant: str) -> None:
    if not any(isinstance(e.shape, Arc | NewtonCurve) for e in piece.elements):
        print("note: seed mode changes arcs and Newton curves only; this piece has none",
              file=sys.stderr)
    cw = [e.where for e in piece.elements if isinstance(e.shape, Arc) and not e.shape.ccw]
    if cw and variant == "matlab":  # the thesis's own defect, kept and shown
        print(f"seed mode (matlab): TrazarArco2 runs no step for a negative sweep (B7): the "
              f"clockwise arcs of {', '.join(dict.fromkeys(cw))} are each one chord "
              "(--seed-variant cpu steps them, as the CPU's F_ClcCirculo does)")
    seed = piece.segments(seed=variant)
    _report_chain(piece)
    print(f"seed mode ({variant}, thesis algorithms): {len(seed)} segments, cut "
          f"{piece.length('cut', seed=variant):.5f} mm, ends at "
          f"({seed[-1].end[0]:.6g}, {seed[-1].end[1]:.6g})" if seed else
          "seed mode: no segments")


def _machine_axes(path: str) -> tuple[tuple[float, float], float]:
    """The axes' `start` (true counts at power-up) and counts per mm from a machine TOML
    (read and checked by the configuration loader): what maps the trace's true positions
    onto work coordinates."""
    from softplc.assembly import load
    from softplc.errors import ConfigError

    try:
        devices = load(path).settings.devices
    except ConfigError as e:
        raise CuttingError(f"--machine {e}") from None
    axes = [devices[n].options for n in ("X", "Y") if n in devices]
    if len(axes) < 2 or not all(hasattr(o, "counts_per_mm") for o in axes):
        raise CuttingError(f"--machine {path}: no servo axes [devices.X] and [devices.Y]")
    return (axes[0].start, axes[1].start), axes[0].counts_per_mm


def _stream(piece: Piece, args: argparse.Namespace) -> int:
    """Stream to the daemon (handshake of regmap.py), then the deviation from the trace."""
    import time

    from softplc.machines.cutting.client import CutClient, fault_text, trace_deviation

    if args.seed:
        print(f"seed mode ({args.seed}): streaming the thesis's path (its arc steps and Newton "
              "evaluation); the trace is measured against the ideal shape")
    with CutClient(args.host, args.port) as client:
        res = client.stream(piece, args.start_at, seed=args.seed)
    state = "interrupted" if res.interrupted else "stopped by a fault" if res.fault else "done"
    print(f"{state}: {res.done} segments in {res.wall:.2f} s (last {res.last_number} of "
          f"{res.total}); the carriage is at ({res.pos_mm[0]:.3f}, {res.pos_mm[1]:.3f}) mm")
    if res.fault:
        print(f"{fault_text(res.fault)} during segment {res.next_number}/{res.total} "
              f"({res.fault_where}): the axes stopped, torch off. Clear the cause (softplc "
              f"cut jog AXIS± MM leaves a switch), softplc cut reset, then resume with "
              f"--start-at {res.next_number}")
        return FAULT_EXIT
    if res.interrupted:
        print(f"resume with --start-at {res.next_number}")
        return 130
    if args.trace:
        start, per_mm = _machine_axes(args.machine)
        time.sleep(0.5)  # the daemon writes its trace every second of simulated time
        origin = (start[0] + res.origin_counts[0], start[1] + res.origin_counts[1])
        rep = trace_deviation(piece, args.trace, origin, per_mm)
        print(f"trace {args.trace}: {rep.samples} torch-on samples, at most "
              f"{rep.worst:.6f} mm from the ideal shape (at {rep.at[0]:.4f}, "
              f"{rep.at[1]:.4f}; chord tolerance {piece.tolerance:g}); last sample "
              f"({rep.end[0]:.6f}, {rep.end[1]:.6f}) mm")
    return 0


#: `softplc cut` exit status when the PLC faulted during the piece.
FAULT_EXIT = 3


def _operate(args: argparse.Namespace) -> int:
    """`softplc cut reset | home | jog AXIS± [MM]` on the daemon's PLC."""
    from softplc.machines.cutting.client import CutClient

    action, extra = args.piece, list(args.action_args)
    want = "AXIS± [MM]" if action == "jog" else ""
    if (action == "jog" and not 1 <= len(extra) <= 2) or (action != "jog" and extra):
        raise CuttingError(f"usage: softplc cut {action} {want}".rstrip())
    with CutClient(args.host, args.port, progress=None) as client:
        if action == "reset":
            st = client.reset()
            print(f"RESET accepted: READY, homed, at ({st.pos_um[0] / 1000:.3f}, "
                  f"{st.pos_um[1] / 1000:.3f}) mm; last segment done {st.seg_done}")
        elif action == "home":
            st = client.home()
            print(f"homed: READY at ({st.pos_um[0] / 1000:.3f}, {st.pos_um[1] / 1000:.3f}) mm")
        else:
            try:
                mm = float(extra[1]) if len(extra) > 1 else 5.0
            except ValueError:
                raise CuttingError(f"jog distance {extra[1]!r}: a number of mm") from None
            moved = client.jog(extra[0], mm)
            st = client.read_state()
            print(f"jog {extra[0].upper()}: moved {moved:.3f} mm, now at "
                  f"({st.pos_um[0] / 1000:.3f}, {st.pos_um[1] / 1000:.3f}) mm")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.piece in ACTIONS and not Path(args.piece).exists():
        return _operate(args)
    args.seed = args.seed_variant or ("matlab" if args.seed else False)
    if args.action_args:
        raise CuttingError(f"unexpected arguments after the piece: {' '.join(args.action_args)}"
                           " (only reset, home and jog take arguments)")
    piece = _load(args)
    for w in piece.warnings:
        print(f"warning: {w}", file=sys.stderr)
    segs = piece.segments()
    cuts = sum(1 for s in segs if s.cut)
    dwells = [s.dwell for s in segs if s.kind == DWELL]
    dwelt = f", {len(dwells)} dwells of {sum(dwells):g} s" if dwells else ""
    print(f"{args.piece}: {piece.name}: {len(segs)} segments ({cuts} cut{dwelt}), cut "
          f"{piece.length('cut'):.5f} mm, move {piece.length('move'):.5f} mm, ends at "
          f"({piece.end[0]:.6g}, {piece.end[1]:.6g}), motion about {piece.duration():.2f} s")
    if args.seed:
        _report_seed(piece, args.seed)
    if not 1 <= args.start_at <= max(len(segs), 1):
        raise CuttingError(f"--start-at {args.start_at}: the piece has {len(segs)} segments")
    if args.simulate is not None:
        _report_simulation(piece, args.simulate, args.seed)
    if args.preview:
        Path(args.preview).parent.mkdir(parents=True, exist_ok=True)
        print(f"preview written to {preview(piece, args.preview, seed=args.seed)}",
              file=sys.stderr)
    if args.frames:
        _write_frames(piece, args.frames)
        print(f"segment words written to {args.frames}", file=sys.stderr)
    if args.dry_run:
        return 0
    if args.trace:  # checked before the cut, not after it: the run is long
        _machine_axes(args.machine)
    return _stream(piece, args)
