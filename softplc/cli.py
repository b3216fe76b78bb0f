"""The `softplc` command. Each subcommand lives in its own module and registers itself here.

A subcommand module exposes `register(subparsers)`, which adds its parser and sets
`func=callable(args) -> int` with `set_defaults`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from softplc.errors import SoftPLCError

# command -> the module that registers it. Order is the order shown in --help. A machine's
# commands live in its package (softplc/machines/NAME/command.py).
COMMAND_MODULES = {
    "check": "softplc.commands.check",
    "run": "softplc.commands.run",
    "repl": "softplc.commands.repl",
    "ladder": "softplc.commands.ladder",
    "draw": "softplc.machines.drawing.command",
    "io": "softplc.commands.io",
    "load": "softplc.commands.load",
    "map": "softplc.commands.map",
    "symbols": "softplc.commands.symbols",
    "cut": "softplc.machines.cutting.command",
    "servo": "softplc.machines.servo.command",
    "tune": "softplc.machines.machining.command",
    "verify": "softplc.commands.verify",
    "replay": "softplc.commands.replay",
    "plant": "softplc.commands.plant",
    "fleet": "softplc.commands.fleet",
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand, or only of `command` when it is one: a command
    then imports only what it needs (`softplc run` starts without loading the G-code host,
    the plots or the servo client), which matters for a daemon started often."""
    parser = argparse.ArgumentParser(
        prog="softplc",
        description="A soft-PLC for Telemecanique Twido Instruction List programs.",
    )
    from softplc import __version__

    parser.add_argument("--version", action="version", version=f"softplc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    names = [command] if command in COMMAND_MODULES else list(COMMAND_MODULES)
    for name in names:
        importlib.import_module(COMMAND_MODULES[name]).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    # the top level has no option taking a value: the first word is the command
    parser = build_parser(next((a for a in argv if not a.startswith("-")), None))
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except SoftPLCError as e:
        print(f"softplc: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
