"""`softplc ladder PROGRAM.il [--svg out.svg | --txt out.txt]`: the program drawn as a
ladder diagram, rung titles included (text to stdout by default)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from softplc.commands._args import add_program_arguments, check_files, load_plc


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "ladder", help="draw a program as a ladder diagram (text or SVG)",
        description="Render every rung of PROGRAM.il as a ladder diagram: contacts (negated "
                    "/, rising P, falling N), coils ( ) (/) (S) (R), comparison and "
                    "operation blocks, parallel branches, function blocks. Text goes to "
                    "stdout unless --txt or --svg names a file. With --config, timer, "
                    "counter, drum and register boxes show their configuration (type, time "
                    "base, preset).")
    add_program_arguments(p)
    out = p.add_mutually_exclusive_group()
    out.add_argument("--svg", type=Path, metavar="FILE", help="write an SVG drawing")
    out.add_argument("--txt", type=Path, metavar="FILE", help="write the text drawing")
    p.add_argument("--ascii", action="store_true", help="plain ASCII instead of box drawing")
    p.add_argument("--rung", action="append", metavar="N|TITLE",
                   help="only this rung (repeatable)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc import ladder
    from softplc.errors import SoftPLCError
    from softplc.il import ast as A
    from softplc.il.parser import parse_file

    blocks = None
    if args.config is not None:  # the configured blocks, for their boxes
        plc = load_plc(args, devices=False)
        program, mem = plc.ast, plc.mem
        blocks = lambda ref: mem.blocks.get(ref.kind, {}).get(ref.index)  # noqa: E731
    else:
        check_files(args)
        program = parse_file(args.program)
    if args.rung:
        picked = []
        for key in args.rung:
            try:
                picked.append(program.rung(key))
            except (KeyError, IndexError):
                raise SoftPLCError(f"no rung {key!r} in {args.program}") from None
        program = A.Program(program.file, program.source, picked, program.section_titles)
    if args.svg:
        args.svg.write_text(ladder.render_program_svg(program, blocks), encoding="utf-8")
        print(f"wrote {args.svg}")
        return 0
    text = ladder.render_program_text(program, ascii=args.ascii, blocks=blocks)
    if args.txt:
        args.txt.write_text(text, encoding="utf-8")
        print(f"wrote {args.txt}")
    else:
        sys.stdout.write(text)
    return 0
