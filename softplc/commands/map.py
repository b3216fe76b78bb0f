"""`softplc map PROGRAM.il [--config X] [--csv FILE]`: the Modbus map of a program."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from softplc.commands._args import add_program_arguments, check_files, load_plc


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "map", help="the Modbus map of a program (an HMI/SCADA tag list, CSV)",
        description="List every %M, %MW, %MD and %MF object PROGRAM.il uses with its "
                    "Modbus table, address, function codes and access (read-only ranges "
                    "of [modbus] read_only and the devices' status words refuse writes), "
                    "then what the program uses that no host can reach (%I, %Q, "
                    "timers...) and how to expose it.",
        epilog="example: softplc map ladder_programs/drawing_table.il "
               "--config ladder_programs/drawing_table.toml --csv tags.csv")
    add_program_arguments(p)
    p.add_argument("--csv", type=Path, metavar="FILE",
                   help="write the tags as CSV ('-' = stdout): tag, address, type, table, "
                        "modbus_address (0-based), reference (00001/40001-based), count, "
                        "read_fc, write_fc, access, program, comment, note")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.il.parser import parse_file
    from softplc.modbus import tags

    if args.config is None:  # the program alone: no read-only ranges, no devices
        check_files(args)
        pmap = tags.build(parse_file(args.program))
    else:
        pmap = tags.of_plc(load_plc(args))
    if args.csv is None:
        sys.stdout.write(tags.to_text(pmap))
        return 0
    text = tags.to_csv(pmap)
    if str(args.csv) == "-":
        sys.stdout.write(text)
    else:
        args.csv.write_text(text, encoding="utf-8")
        print(f"wrote {args.csv}: {len(pmap.tags)} tags, {len(pmap.hidden)} objects not on "
              f"the map", file=sys.stderr)
    return 0
