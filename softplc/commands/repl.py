"""`softplc repl PROGRAM.il [--config machine.toml]`: the interactive debugger, on the
virtual clock, with the machine's simulated devices attached."""

from __future__ import annotations

import argparse
from pathlib import Path

from softplc.commands._args import add_program_arguments, existing_file, load_plc
from softplc.errors import SoftPLCError

PLANT_SUFFIX = ".toml"  # a program is Instruction List text: a .toml is a plant file


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "repl", help="debug a program interactively (breakpoints, stepping, ladder view)",
        description="Load PROGRAM.il on the virtual clock (with the simulated devices of the "
                    "machine configuration) and debug it: scan/step/stepi/run/continue, "
                    "breakpoints on rungs, labels and conditions, watches, print/set/force, "
                    "the live ladder view of a rung, going back in time. Given a plant "
                    "file (plant.toml), the whole plant on its one clock: every "
                    "controller stepped together, CONTROLLER:OBJECT, 'ctl NAME'. 'help' "
                    "inside lists the commands.")
    add_program_arguments(p)
    p.add_argument("-x", "--execute", action="append", default=[], metavar="CMD",
                   help="run this debugger command first (repeatable); end with -x quit "
                        "for a batch run")
    p.add_argument("--history", type=int, default=1000,
                   help="scans kept for 'back' (default 1000)")
    p.add_argument("--replay", type=Path, metavar="CEX.json",
                   help="feed each scan the inputs of a counterexample written by "
                        "'softplc verify --cex' (the first one in the file)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.debug.repl import run_repl
    from softplc.debug.session import Session
    if args.program.suffix.lower() == PLANT_SUFFIX:
        return run_plant(args)
    plc = load_plc(args, clock="virtual")
    replaying = ""
    if args.replay is not None:
        from softplc.verify.replay import read_cex, replay_hook
        cex = read_cex(args.replay)["counterexamples"][0]
        plc.before_scan.append(replay_hook(plc, cex))
        replaying = (f"\nreplaying {args.replay}: {cex['requirement']} breaks within "
                     f"{len(cex['scans'])} scans ('scan {len(cex['scans'])}' to get there)")
    session = Session(plc, args.program, history=max(1, args.history))
    n = len(plc.ast.rungs)
    intro = (f"softplc debugger: {args.program} ({n} rungs), scan period "
             f"{plc.scan_period * 1000:g} ms, virtual clock"
             + (f", devices: {', '.join(plc.devices)}" if plc.devices else "")
             + replaying + "\ntype 'help' for the commands, 'quit' to leave")
    try:
        return run_repl(session, intro, args.execute)
    finally:
        plc.close()


def run_plant(args: argparse.Namespace) -> int:
    """The debugger over every controller of a plant file (docs/plant.md)."""
    from softplc.debug.plant_session import PlantSession
    from softplc.debug.repl import run_repl
    from softplc.plant import Plant
    if args.config is not None or args.replay is not None:
        raise SoftPLCError("--config and --replay are for one program; a plant file names "
                           "each controller's configuration")
    plant = Plant.from_file(existing_file(args.program, "plant"))
    session = PlantSession(plant, history=max(1, args.history))
    intro = (f"softplc debugger: plant {plant.name} ({args.program}): "
             f"{', '.join(plant.controllers)}"
             + (f"; devices: {', '.join(plant.devices)}" if plant.devices else "")
             + f", one virtual clock\nfocus: {session.focus} ('ctl NAME' to change; "
             "NAME:OBJECT names another's); 'help' for the commands, 'quit' to leave")
    try:
        return run_repl(session, intro, args.execute)
    finally:
        plant.close()
