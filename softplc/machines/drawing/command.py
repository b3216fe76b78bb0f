"""`softplc draw FILE.gcode`: check, preview and stream a drawing to the table's PLC."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from softplc.commands._args import add_connection_arguments, size_arg

if TYPE_CHECKING:
    from softplc.machines.gcode import GCodeConfig

_EXAMPLES = """\
examples:
  softplc draw square.gcode --dry-run --preview square.png
  softplc draw star.gcode --host 127.0.0.1 --port 5020 --trace trace.csv
  softplc draw star.gcode --start-at 17        # resume after an interruption
"""


_table = size_arg("table size", "cm", "25x25")


def _plot_drawn(trace: str, since: float | None, steps: list, out: str,
                cfg: GCodeConfig) -> None:
    """The drawing recorded by the daemon (this run only) over the programmed path, in cm
    like the preview."""
    from softplc.machines.drawing.deviation import load_trace
    from softplc.machines.drawing.trace import plot_samples

    rows = load_trace(trace)
    if since is not None:
        rows = rows[rows[:, 0] > since]
    programmed = [(s.start, s.end) for s in steps if s.pen_down and s.start != s.end]
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    spu = cfg.steps_per_unit
    plot_samples(rows, out, programmed, units="units", unit_name="cm",
                 steps_per_unit=(spu, spu),
                 travel_steps=(cfg.table_width * spu, cfg.table_height * spu),
                 title=f"{Path(trace).name}: drawn over programmed", full_area=True)
    print(f"drawing plotted to {out}", file=sys.stderr)


def _wait_for_trace(path: str, since: float | None, end: tuple[int, int] | None,
                    timeout: float) -> bool:
    """Give the daemon time to flush the end of the run: the trace's last sample is newer
    than `since`, pen up at `end` (steps), where the stream left the pen. A pen-up sample
    elsewhere is only a travel move: the trace is flushed once a (simulated) second, so it
    may hold part of the drawing only. True if the end was seen."""
    deadline = time.monotonic() + timeout
    while True:
        from softplc.machines.drawing.deviation import last_sample

        last = last_sample(path)
        if last and (since is None or last[0] > since) and not last[3] and (
                end is None or (last[1], last[2]) == tuple(end)):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "draw", help="send a G-code drawing to the drawing table over Modbus TCP",
        description="Read a G-code drawing (ordinary G-code or the seed's VB dialect),\n"
                    "check it against the table, optionally plot it, and stream it segment\n"
                    "by segment to the PLC over Modbus TCP: %MW0/%MW1 target steps, %MW5\n"
                    "pen, %MW3 := 120 starts a segment, %MW10 = 100 while moving.",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", metavar="FILE.gcode", help="the G-code program")
    g = add_connection_arguments(p)
    g.add_argument("--device-id", type=int, default=1,
                   help="Modbus unit id (default %(default)s)")
    g.add_argument("--poll", type=float, default=0.05, metavar="SECONDS",
                   help="state polling interval (default %(default)s)")
    g.add_argument("--request-timeout", type=float, default=1.0, metavar="SECONDS",
                   help="timeout of one Modbus request (default %(default)s)")
    g.add_argument("--retries", type=int, default=3,
                   help="retries of a failed Modbus request (default %(default)s)")
    g.add_argument("--idle-timeout", type=float, default=60.0, metavar="SECONDS",
                   help="wait for the PLC to be idle before a segment (default %(default)s)")
    g.add_argument("--accept-timeout", type=float, default=5.0, metavar="SECONDS",
                   help="wait for the PLC to accept a segment (default %(default)s)")
    g.add_argument("--move-timeout", type=float, default=120.0, metavar="SECONDS",
                   help="wait for one segment's move to end (default %(default)s)")
    g.add_argument("--start-at", type=int, default=1, metavar="N",
                   help="resume from segment N (1-based; printed when a run stops)")
    g.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    g.add_argument("--trace", metavar="FILE.csv",
                   help="after drawing, read the daemon's trace (t,x,z,pen,missed) and "
                        "report the largest deviation from the programmed path")
    g.add_argument("--plot", metavar="OUT.png|OUT.svg",
                   help="with --trace: plot what was drawn over the programmed path")
    g.add_argument("--trace-wait", type=float, default=3.0, metavar="SECONDS",
                   help="how long to wait for the daemon to flush the trace (default "
                        "%(default)s)")
    r = p.add_argument_group("reading the program")
    r.add_argument("--plane", default="XZ", type=str.upper, choices=["XZ", "XY", "YZ"],
                   help="drawing plane; the other axis is the pen (default %(default)s, "
                        "the seed table: X, Z plane and Y1/Y0 pen)")
    r.add_argument("--dialect", choices=["auto", "seed"], default="auto",
                   help="auto (default): refuse a program whose Y words are ambiguous in the "
                        "XZ plane (ordinary XY G-code read as the seed's Y1/Y0 pen flag); "
                        "seed: always read Y as the pen flag")
    r.add_argument("--pen", choices=["flag", "depth"], default=None,
                   help="pen axis meaning: flag = nonzero is down (default for Y), "
                        "depth = down while <= 0 (default for Z or X)")
    r.add_argument("--units", choices=["cm", "mm", "in"], default="cm",
                   help="units before any G20/G21/G70/G71 (default %(default)s)")
    r.add_argument("--steps-per-unit", type=float, default=111.11, metavar="STEPS",
                   help="motor steps per cm (default %(default)s)")
    r.add_argument("--table", type=_table, default=(25.0, 25.0), metavar="WxH",
                   help="table size in cm (default 25x25)")
    r.add_argument("--chord-tolerance", type=float, default=0.01, metavar="CM",
                   help="largest distance of an arc's chords from the arc "
                        "(default %(default)s)")
    o = p.add_argument_group("output")
    o.add_argument("--preview", metavar="OUT.png|OUT.svg",
                   help="plot the path (pen down solid, pen-up travel dashed)")
    o.add_argument("--dry-run", action="store_true",
                   help="parse, report and preview only; do not connect")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # imported here: the G-code package pulls in numpy and the Modbus client, which
    # `softplc --help` does not need
    from softplc.machines.drawing import DrawClient, max_deviation
    from softplc.machines.drawing.deviation import last_sample
    from softplc.machines.gcode import GCodeConfig, parse_file
    from softplc.machines.gcode.preview import preview

    cfg = GCodeConfig(plane=args.plane, pen=args.pen, units=args.units, dialect=args.dialect,
                      table_width=args.table[0], table_height=args.table[1],
                      chord_tolerance=args.chord_tolerance, steps_per_unit=args.steps_per_unit)
    prog = parse_file(args.file, cfg)
    for w in prog.warnings:
        print(f"warning: {w}", file=sys.stderr)
    steps = prog.steps()
    down = sum(1 for s in steps if s.pen_down and s.start != s.end)
    print(f"{args.file}: {len(steps)} segments ({down} pen down), "
          f"{prog.pen_down_length():.2f} cm drawn", file=sys.stderr)
    if args.preview:
        out = preview(prog, args.preview)
        print(f"preview written to {out}", file=sys.stderr)
    if args.dry_run:
        return 0
    client = DrawClient(args.host, args.port, device_id=args.device_id,
                        poll_interval=args.poll, request_timeout=args.request_timeout,
                        retries=args.retries, idle_timeout=args.idle_timeout,
                        accept_timeout=args.accept_timeout, move_timeout=args.move_timeout,
                        progress=None if args.no_progress else sys.stderr)
    # The daemon's trace covers every run since it started: only count what comes after now.
    before = last_sample(args.trace) if args.trace else None
    with client:
        result = client.stream(steps, start_at=args.start_at)
    if result.interrupted:
        print(f"stopped after segment {result.last_number} of {result.total}, pen up at "
              f"{result.point} steps; resume with --start-at {result.next_number}",
              file=sys.stderr)
        return 130
    print(f"done: {result.sent} segments sent ({client.frames_sent} frames)", file=sys.stderr)
    if args.trace:
        since = before[0] if before else None
        if not _wait_for_trace(args.trace, since, result.point, args.trace_wait):
            print(f"warning: the trace {args.trace} does not reach the end of the drawing "
                  f"yet (waited {args.trace_wait:g} s; --trace-wait)", file=sys.stderr)
        dev = max_deviation(steps, args.trace, cfg.steps_per_unit, since=since)
        print(dev)
        if args.plot:
            _plot_drawn(args.trace, since, steps, args.plot, cfg)
    return 0
