"""Arguments shared by the subcommands: argument types, and the program and configuration
arguments every command takes, in one place:

    add_program_arguments(parser)          # PROGRAM.il and --config FILE.toml
    plc = load_plc(args, clock="virtual")  # both files checked, then PLC.from_file
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from softplc.errors import ConfigError, SoftPLCError


def size_arg(what: str, unit: str, example: str) -> Callable[[str], tuple[float, float]]:
    """An argparse type for `WxH` sizes ("25x25", or "25" for a square)."""

    def parse(text: str) -> tuple[float, float]:
        try:
            w, _, h = text.lower().partition("x")
            return float(w), float(h or w)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} {text!r}: expected WxH in {unit}, "
                                             f"e.g. {example}") from None

    return parse


# = softplc.modbus.regmap.DEFAULT_PORT, not imported from there: importing softplc.modbus
# takes ~0.7 s, which every `softplc --help` would pay (tests/e2e/test_check_command.py checks it)
DEFAULT_MODBUS_PORT = 5020


def port(value: Any) -> int:
    """An argparse type for TCP ports: 0..65535 (0 = any free port)."""
    try:
        v = int(value)
    except (TypeError, ValueError):
        v = -1
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"bad port {value!r} (0..65535; 0 = any free port)")
    return v


def add_connection_arguments(p: argparse.ArgumentParser) -> Any:
    """The "connection" group of a Modbus host command (draw, cut, servo): --host, --port.
    Returns the group, for the command's own connection options."""
    g = p.add_argument_group("connection")
    g.add_argument("--host", default="127.0.0.1", help="PLC address (default %(default)s)")
    g.add_argument("--port", type=port, default=DEFAULT_MODBUS_PORT,
                   help="Modbus TCP port (default %(default)s)")
    return g


PROGRAM_HELP = "Instruction List program (.il, or a TwidoSuite List export)"
CONFIG_HELP = ("machine/PLC configuration (TOML): scan period, timers, counters, constants, "
               "simulated devices, [modbus], [daemon]")


def add_program_arguments(p: argparse.ArgumentParser) -> None:
    """PROGRAM and --config, the same for every command."""
    p.add_argument("program", type=Path, metavar="PROGRAM.il", help=PROGRAM_HELP)
    p.add_argument("--config", type=Path, metavar="FILE.toml", help=CONFIG_HELP)


def existing_file(path: Path, what: str, error: type[SoftPLCError] = SoftPLCError) -> Path:
    """`path`, or a clear error if there is no such file."""
    if not path.exists():
        raise error(f"{path}: no such file ({what})")
    if path.is_dir():
        raise error(f"{path}: is a folder, not a {what} file")
    return path


def check_files(args: argparse.Namespace) -> None:
    existing_file(args.program, "program")
    if args.config is not None:
        existing_file(args.config, "configuration", ConfigError)


def load_plc(args: argparse.Namespace, **kw: Any) -> Any:
    """The PLC of `args.program` with `args.config` (keyword arguments go to `PLC`)."""
    from softplc.plc import PLC

    check_files(args)
    return PLC.from_file(args.program, config=args.config, **kw)
