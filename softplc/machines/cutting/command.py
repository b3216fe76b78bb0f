"""`softplc cut PIECE`: check a cutting-table piece, preview it, list the PLC words;
`softplc cut reset | home | jog AXIS± [MM]`: the operator's commands.

The command validates (schema, geometry, work area), reports, previews, writes the segment
words and, without --dry-run, streams the piece to the daemon running
ladder_programs/cutting_table.il (`softplc.machines.cutting.client`), then reports how far the
torch-on trace got from the ideal shape. The work is in `_cut_run.py`, imported only when
the command runs (the cutting library loads pydantic: every other `softplc` command stays
as quick to start).
"""

from __future__ import annotations

import argparse

from softplc.commands._args import add_connection_arguments, size_arg
from softplc.machines.examples import example

_EXAMPLES = """\
examples (after P=ladder_programs/pieces):
  softplc cut $P/achaflanado.toml --dry-run --preview out/e3.png
  softplc cut $P/polinomio.toml --dry-run --seed --preview out/e5.svg
  softplc cut $P/rounded_rectangle.gcode --dry-run --frames out/e3.csv
  softplc run ladder_programs/cutting_table.il \\
      --config ladder_programs/cutting_table.toml \\
      --port 5020 --speed max --trace out/cut.csv &
  softplc cut $P/achaflanado.toml --port 5020 --trace out/cut.csv
  softplc cut jog X- 5 --port 5020   (in FAULT: leave a made switch)
  softplc cut reset --port 5020      (then --start-at N as printed)
  softplc cut home --port 5020       (home again from READY)
"""

_area = size_arg("work area", "mm", "240x240")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "cut", help="check, preview and stream a piece to the cutting table",
        description="Read a cutting-table piece (.toml; G-code: XY plane, mm, G00 move,\n"
                    "G01-G03 cut, G04 dwell; .dxf: LINE, ARC, CIRCLE, LWPOLYLINE), check its\n"
                    "geometry and the work area, report it, plot it\n"
                    "and list the segment words the host sends (%MD100/%MD102 end in um,\n"
                    "%MF104 speed, %MW106 kind, %MW107 number, %MW108 INICIO), then stream\n"
                    "it to the PLC (Modbus TCP) with progress and ETA; Ctrl-C stops the axes\n"
                    "with the torch off, and so does a fault (both print the --start-at N\n"
                    "that resumes). Operator: `reset` (RESET in FAULT), `home` (home again\n"
                    "from READY), `jog X+|X-|Y+|Y- [MM]` (in FAULT, default 5 mm).",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("piece", metavar="PIECE",
                   help="the piece: FILE.toml, FILE.gcode or FILE.dxf; or reset, home, jog")
    p.add_argument("action_args", nargs="*", metavar="ARG",
                   help="jog: the axis and direction (X+, X-, Y+, Y-), then the distance "
                        "in mm (default 5)")
    r = p.add_argument_group("piece values", "G-code, DXF: these or the defaults; TOML: "
                             "override its keys")
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
                        "Newton without its last term) and overlay it on the preview; "
                        "when streaming, send that path instead (the trace report then "
                        "shows what the machine cuts against the ideal shape)")
    o.add_argument("--seed-variant", choices=("matlab", "cpu"), default=None,
                   help="the thesis's arc code in seed mode (implies --seed): matlab "
                        "(default; TrazarArco2: a CW arc runs no step, one chord, B7) or "
                        "cpu (F_ClcCirculo: 0.03 rad steps with the sign of θ, "
                        "floor(|θ|/α), TRUNC to 0.001)")
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
    g = add_connection_arguments(p)
    g.add_argument("--start-at", type=int, default=1, metavar="N",
                   help="resume from segment N (1-based)")
    g.add_argument("--trace", metavar="TRACE.csv",
                   help="the daemon's trace file (softplc run --trace): report the torch-on "
                        "samples' distance from the ideal shape after the run")
    g.add_argument("--machine", default=str(example("cutting_table.toml")),
                   metavar="TOML", help="machine config of the daemon, for the trace's "
                                        "axis start and counts per mm (default: the shipped "
                                        "cutting_table.toml, whatever the current folder)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.machines.cutting.run import run as run_cut

    return run_cut(args)
