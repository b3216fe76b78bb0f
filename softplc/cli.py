"""The `softplc` command. Each subcommand lives in its own module and registers itself here.

A subcommand module exposes `register(subparsers)`, which adds its parser and sets
`func=callable(args) -> int` with `set_defaults`.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .errors import SoftPLCError

# module path -> registered subcommands. Order is the order shown in --help.
COMMAND_MODULES = [
    "softplc.commands.check",
    "softplc.commands.run",
    "softplc.commands.repl",
    "softplc.commands.ladder",
    "softplc.commands.draw",
    "softplc.commands.io",
    "softplc.commands.load",
    "softplc.commands.map",
    "softplc.commands.symbols",
    "softplc.commands.cut",
    "softplc.commands.servo",
    "softplc.commands.tune",
    "softplc.commands.verify",
]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand, or only of `command` when it is one: a command
    then imports only what it needs (`softplc run` starts without loading the G-code host,
    the plots or the servo client), which matters for a daemon started often."""
    parser = argparse.ArgumentParser(
        prog="softplc",
        description="A soft-PLC for Telemecanique Twido Instruction List programs.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"softplc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    only = f"softplc.commands.{command}"
    for modname in [only] if only in COMMAND_MODULES else COMMAND_MODULES:
        importlib.import_module(modname).register(sub)
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
