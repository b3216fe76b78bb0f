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
    "softplc.commands.cut",
    "softplc.commands.servo",
    "softplc.commands.tune",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="softplc",
        description="A soft-PLC for Telemecanique Twido Instruction List programs.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"softplc {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for modname in COMMAND_MODULES:
        importlib.import_module(modname).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
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
