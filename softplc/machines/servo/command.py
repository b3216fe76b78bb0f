"""`softplc servo TEST`: the thesis's tuning moves on the servo XY table over Modbus TCP."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from softplc.commands._args import add_connection_arguments

_EXAMPLES = """\
examples (daemon: softplc run ladder_programs/servo_table.il --config
          ladder_programs/servo_table.toml):
  softplc servo scurve --axis X --start --from -80000 --plot x-scurve.png
  softplc servo scurve --axis Y --from -128000 --repeat 2
  softplc servo step --axis X --from -64000 --distance 100 --plot step.svg
  softplc servo parabolic --axis X --distance -14336 --time 330
  softplc servo openloop --axis X --output -1 --time 50
  softplc servo set I130=8000 I133=12000
  softplc servo get I130 I133
simulated here, every servo tick gathered (no daemon):
  softplc servo step-return --sim --distance 1000 --dwell 300 --plot sr.png
  softplc servo compare I130=12000 --move step --distance 1000 --plot cmp.png
  softplc servo disturb --sim --load 150 --plot load.png
"""

TESTS = ("scurve", "trapezoid", "step", "step-return", "parabolic", "openloop")
ACTIONS = ("compare", "disturb", "get", "set")
DEFAULT_DISTANCE = {"scurve": 14336, "trapezoid": 14336, "step": 100, "step-return": 100,
                    "parabolic": 14336, "openloop": 0}


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "servo", help="run tuning moves on the servo XY table over Modbus TCP",
        description="Run one of PMACTuningPro's tuning moves on an axis of the servo XY\n"
                    "table (ladder_programs/servo_table.il), print the max following\n"
                    "error (counts and micrometres) and plot commanded, actual and\n"
                    "following error against time. The defaults are the thesis's S-curve\n"
                    "test (TABLA 4-3): 14,336 counts at 4,177,920 counts/min, Ixx20 =\n"
                    "125 ms, Ixx21 = 40 ms. With --sim the move runs on a simulated axis\n"
                    "here, every servo tick gathered (rise, overshoot, settling, max FE);\n"
                    "compare runs one move with two gain sets; disturb applies a step of\n"
                    "load torque; get/set read and write I-variables of the running axes.",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("test", choices=TESTS + ACTIONS, metavar="TEST",
                   help="a move (%(choices)s): compare runs a move with two gain sets, "
                        "disturb applies a load step, get/set read/write I-variables")
    p.add_argument("ivars", nargs="*", metavar="IVAR[=VALUE]",
                   help="get: I130 ...; set: I130=8000 ...; compare: the second gain set")
    p.add_argument("--axis", choices=("X", "Y"), default="X", help="default %(default)s")
    p.add_argument("--distance", type=int, metavar="COUNTS",
                   help="relative move, counts (default: 14336; step 100)")
    p.add_argument("--speed", type=int, default=4_177_920 // 60, metavar="COUNTS/S",
                   help="S-curve/trapezoid speed (default %(default)s = 4,177,920 counts/min)")
    p.add_argument("--acc", type=int, default=125, metavar="MS", help="Ixx20 (default 125)")
    p.add_argument("--scurve", type=int, default=40, metavar="MS", help="Ixx21 (default 40)")
    p.add_argument("--time", type=int, default=0, metavar="MS",
                   help="parabolic move time (default 330) / open-loop time (default 50)")
    p.add_argument("--output", type=float, default=1.0, metavar="PCT",
                   help="open-loop output, %% of Ixx69 (default %(default)s)")
    p.add_argument("--from", dest="start_pos", type=int, metavar="COUNTS",
                   help="first move the axis there, approaching in the direction of the "
                        "test move (X -80000, Y -128000 in the thesis)")
    p.add_argument("--repeat", type=int, default=1, metavar="N",
                   help="N moves, alternating forward and back (default %(default)s)")
    p.add_argument("--settle", type=float, default=0.5, metavar="SECONDS",
                   help="rest after each move, servo time (default %(default)s)")
    p.add_argument("--start", action="store_true",
                   help="start the cell (remote start, homing X then Y) if it is not")
    p.add_argument("--counts-per-mm", type=float, default=409.6,
                   help="for micrometres (default %(default)s)")
    p.add_argument("--plot", metavar="OUT.png|OUT.svg", help="plot the last move")
    s = p.add_argument_group("simulated here (servo-rate gather)")
    s.add_argument("--sim", action="store_true",
                   help="run the move on a simulated axis in this process (compare does)")
    s.add_argument("--config", metavar="TOML",
                   help="machine TOML of the simulated axis (default: the project's "
                        "ladder_programs/servo_table.toml)")
    s.add_argument("--set", dest="gains", action="append", default=[],
                   metavar="I130=8000", help="gains of the (first) simulated set")
    s.add_argument("--move", choices=TESTS[:5], default="step",
                   help="compare: the move (default %(default)s)")
    s.add_argument("--dwell", type=int, default=300, metavar="MS",
                   help="step-return: dwell before the return (default %(default)s)")
    s.add_argument("--load", type=float, default=150.0, metavar="BITS",
                   help="disturb: the load step, DAC bits (default %(default)s)")
    g = add_connection_arguments(p)
    g.add_argument("--poll", type=float, default=0.002, metavar="SECONDS",
                   help="status polling interval (default %(default)s)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.machines.servo.client import (  # heavy: not for `softplc --help`
        ServoClient,
        plot_tuning,
    )

    if args.test in ("get", "set"):
        return _ivars(args)
    if args.sim or args.test == "compare" or (args.test == "disturb" and args.sim):
        return _simulated(args)
    if args.test == "disturb":
        return _ivars(args)
    if args.test == "step-return":
        print("step-return: use --sim (a servo-rate gather); over Modbus use step with "
              "--repeat 2", file=sys.stderr)
        return 2

    distance = args.distance if args.distance is not None else DEFAULT_DISTANCE[args.test]
    move_ms = args.time or (50 if args.test == "openloop" else 330)
    with ServoClient(args.host, args.port, poll=args.poll, progress=sys.stderr) as sc:
        sc.ensure_ready(args.start)
        if args.start_pos is not None:
            # Approach in the direction of the first move, as a tuner takes up backlash:
            # friction and the integrator are then as that move leaves them.
            before = args.start_pos - distance
            print(f"moving {args.axis} to {before}, then {args.start_pos} ...",
                  file=sys.stderr)
            sc.move_to(args.axis, before)
            sc.move_to(args.axis, args.start_pos, settle=args.settle)
        result = None
        for i in range(args.repeat):
            d = distance if i % 2 == 0 else -distance
            print(f"{args.test} move {i + 1}/{args.repeat} on {args.axis}: {d:+d} counts",
                  file=sys.stderr)
            result = sc.tuning_move(args.test, args.axis, d, args.speed, args.acc,
                                    args.scurve, move_ms, args.output, settle=args.settle)
            um = result.fe_max / args.counts_per_mm * 1000
            print(f"{args.test} {args.axis} move {i + 1}: moved {result.moved} counts, "
                  f"max |FE| {result.fe_max:.2f} counts = {um:.1f} um "
                  f"({len(result.samples)} samples polled)")
        if args.plot and result is not None:
            Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
            plot_tuning(result, args.plot, args.counts_per_mm)
            print(f"plot written to {args.plot}", file=sys.stderr)
    return 0


def _ivars(args: argparse.Namespace) -> int:
    """get/set I-variables (and disturb's load word) of the running table over Modbus."""
    from softplc.machines.servo.client import (
        ServoClient,
        get_ivar,
        parse_ivars,
        set_disturbance,
        set_ivar,
    )

    items = [] if args.test == "disturb" else parse_ivars(args.ivars, args.test == "set")
    with ServoClient(args.host, args.port, poll=args.poll) as sc:
        if args.test == "disturb":
            set_disturbance(sc, args.axis, args.load)
            print(f"load disturbance on {args.axis}: {args.load:g} bits")
        for name, value in items:
            now = set_ivar(sc, name, value) if args.test == "set" else get_ivar(sc, name)
            print(f"{name} = {now:g}")
    return 0


def _simulated(args: argparse.Namespace) -> int:
    """A move (or two gain sets on one move, or a load step) on a simulated axis."""
    from softplc.machines.servo import tuning as st

    gains = st.parse_gains(args.gains)
    label = " ".join(args.gains)
    config = args.config or st.DEFAULT_CONFIG
    if args.test == "disturb":
        caps = [st.disturbance(args.axis, args.load, config=config, gains=gains,
                               label=label)]
        title = f"load step of {args.load:g} bits on {args.axis} (servo-rate gather)"
    else:
        move = args.move if args.test == "compare" else args.test
        d = args.distance if args.distance is not None else DEFAULT_DISTANCE[move]
        kw = dict(config=config, speed=args.speed, time_ms=args.time or 330,
                  dwell_ms=args.dwell)
        caps = [st.run_move(move, args.axis, d, gains=gains, label=label, **kw)]
        if args.test == "compare":
            b = st.parse_gains(args.ivars)
            caps.append(st.run_move(move, args.axis, d, gains={**gains, **b},
                                    label=" ".join(args.ivars), **kw))
        title = f"{move} move of {d} counts on {args.axis} (servo-rate gather)"
    print(st.table(caps))
    if args.plot:
        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        st.plot(caps, args.plot, title)
        print(f"plot written to {args.plot}", file=sys.stderr)
    return 0
