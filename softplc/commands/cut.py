"""`softplc cut PIECE`: check a cutting-table piece, preview it, list the PLC words.

Today the command validates (schema, geometry, work area), reports, previews and writes the
segment words the host will send; streaming to the PLC comes with the cutting-table device
(issue 13, device round) and plugs in at `_stream`, with the connection options already
parsed here.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from ..cutting import (
    Arc,
    CuttingError,
    NewtonCurve,
    Piece,
    load_piece,
    preview,
    segment_words,
    split_line,
)
from ..cutting.motion import simulate
from ..cutting.regmap import FRAME_LEN, SEG_BASE
from ..cutting.seed import run_trigger_chain, thesis_split
from ._args import size_arg

_EXAMPLES = """\
examples:
  softplc cut ladder_programs/pieces/achaflanado.toml --dry-run --preview out/e3.png
  softplc cut ladder_programs/pieces/polinomio.toml --dry-run --seed --preview out/e5.svg
  softplc cut ladder_programs/pieces/rounded_rectangle.gcode --dry-run --frames out/e3.csv
"""


_area = size_arg("work area", "mm", "240x240")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "cut", help="check, preview and (device round) stream a piece to the cutting table",
        description="Read a cutting-table piece (.toml, or G-code: XY plane, mm, G00 move,\n"
                    "G01-G03 cut), check its geometry and the work area, report it, plot it\n"
                    "and list the segment words the host sends (%MD100/%MD102 end in um,\n"
                    "%MF104 speed, %MW106 kind, %MW107 number, %MW108 INICIO).\n"
                    "Streaming to the PLC comes with the cutting-table device: use --dry-run.",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("piece", metavar="PIECE", help="the piece: FILE.toml or FILE.gcode")
    r = p.add_argument_group("piece values (G-code: these or the defaults; TOML: override "
                             "the file's keys when given)")
    r.add_argument("--speed", type=float, metavar="MM/S",
                   help="cutting speed (G-code: when the program has no F; default 2)")
    r.add_argument("--move-speed", type=float, metavar="MM/S",
                   help="positioning (G00) speed (default: the cutting speed)")
    r.add_argument("--accel", type=float, metavar="MM/S2",
                   help="path acceleration (default 100)")
    r.add_argument("--tolerance", type=float, metavar="MM",
                   help="chord tolerance of arcs (default 0.01)")
    r.add_argument("--work-area", type=_area, metavar="WxH",
                   help="work area in mm (default 240x240)")
    o = p.add_argument_group("output")
    o.add_argument("--preview", metavar="OUT.png|OUT.svg",
                   help="plot the piece in mm (cuts solid, moves dashed)")
    o.add_argument("--seed", action="store_true",
                   help="also compute the thesis's path (seed mode: arcs by round(θ/α), "
                        "Newton without its last term) and overlay it on the preview")
    o.add_argument("--frames", metavar="OUT.csv",
                   help="write every segment's words (%%MW100-%%MW108) and the axis split "
                        "the PLC should compute (speeds, accelerations, time) to a CSV file")
    o.add_argument("--simulate", type=float, nargs="?", const=0.01, default=None,
                   metavar="DT",
                   help="run the segments on ideal axes (trapezoids, the corrected split; "
                        "with --seed also the thesis's path and split), sampled every DT s "
                        "(default 0.01), and report the largest distance of the torch-on "
                        "path from the ideal shape")
    o.add_argument("--dry-run", action="store_true",
                   help="check, report and write outputs only; do not connect")
    g = p.add_argument_group("connection (used from the device round on)")
    g.add_argument("--host", default="127.0.0.1", help="PLC address (default %(default)s)")
    g.add_argument("--port", type=int, default=5020, help="Modbus TCP port (default %(default)s)")
    g.add_argument("--start-at", type=int, default=1, metavar="N",
                   help="resume from segment N (1-based)")
    p.set_defaults(func=run)


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
                        "vx_mm_s", "vy_mm_s", "ax_mm_s2", "ay_mm_s2", "duration_s"])
            for s in piece.segments():
                sw = segment_words(s)
                # what the PLC should compute for this segment (the corrected split)
                split = split_line(s.start, s.end, s.speed, piece.accel)
                w.writerow([s.number, s.kind, f"{s.end[0]:.6f}", f"{s.end[1]:.6f}",
                            f"{s.speed:g}", s.where, sw.x_um, sw.y_um, sw.kind, sw.number,
                            *sw.frame(),
                            *(f"{v:.9g}" for v in (split.x.speed, split.y.speed,
                                                   split.x.accel, split.y.accel,
                                                   split.duration))])
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


def _report_simulation(piece: Piece, dt: float, seed: bool) -> None:
    runs = [("corrected", piece.segments(), split_line)]
    if seed:
        runs.append(("thesis (seed mode, equal accelerations)", piece.segments(seed=True),
                     thesis_split))
    for name, segs, split in runs:
        samples = simulate(segs, piece.accel, dt, split)
        worst, at = max(((piece.deviation((s.x, s.y)), (s.x, s.y)) for s in samples
                         if s.torch), default=(0.0, piece.start))
        print(f"simulated, {name}: {samples[-1].t if samples else 0:.3f} s of motion, "
              f"{len(samples)} samples (dt {dt:g} s); the torch-on path is at most "
              f"{worst:.6f} mm from the ideal shape (at {at[0]:.4f}, {at[1]:.4f}; chord "
              f"tolerance {piece.tolerance:g})")


def _stream(piece: Piece, args: argparse.Namespace) -> int:
    """The device round's streaming client plugs in here (handshake of regmap.py)."""
    raise CuttingError("streaming to the PLC needs the cutting-table device and program "
                       "(issue 13, device round); run with --dry-run to check and preview")


def run(args: argparse.Namespace) -> int:
    piece = _load(args)
    for w in piece.warnings:
        print(f"warning: {w}", file=sys.stderr)
    segs = piece.segments()
    cuts = sum(1 for s in segs if s.cut)
    print(f"{args.piece}: {piece.name}: {len(segs)} segments ({cuts} cut), cut "
          f"{piece.length('cut'):.5f} mm, move {piece.length('move'):.5f} mm, ends at "
          f"({piece.end[0]:.6g}, {piece.end[1]:.6g}), motion about {piece.duration():.2f} s")
    if args.seed:
        if not any(isinstance(e.shape, Arc | NewtonCurve) for e in piece.elements):
            print("note: seed mode changes arcs and Newton curves only; this piece has none",
                  file=sys.stderr)
        seed = piece.segments(seed=True)
        _report_chain(piece)
        print(f"seed mode (thesis algorithms): {len(seed)} segments, cut "
              f"{piece.length('cut', seed=True):.5f} mm, ends at "
              f"({seed[-1].end[0]:.6g}, {seed[-1].end[1]:.6g})" if seed else
              "seed mode: no segments")
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
    return _stream(piece, args)
