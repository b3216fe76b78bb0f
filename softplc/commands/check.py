"""`softplc check PROGRAM.il`: parse and compile a program, report every problem."""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from dataclasses import asdict

from softplc.commands._args import add_program_arguments, check_files, load_plc
from softplc.errors import ConfigError, Diagnostic, ProgramError, SoftPLCError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check", help="parse and compile a program; list its rungs or every error",
        description="Parse and compile an Instruction List program with its configuration. "
                    "Prints every error as FILE:LINE:COL (exit 1), else a summary.")
    add_program_arguments(p)
    p.add_argument("--rungs", action="store_true", help="list the rungs with their titles")
    p.add_argument("--python", action="store_true",
                   help="print the Python code the rungs compile to")
    p.add_argument("--format", action="store_true",
                   help="print the program formatted in TwidoSuite export layout, comments "
                        "kept (stdout; messages go to stderr); only the syntax is checked "
                        "unless --config is given")
    p.add_argument("--in-place", action="store_true",
                   help="with --format: rewrite PROGRAM.il instead of printing it")
    p.add_argument("--json", action="store_true",
                   help="print the result as JSON (errors with file, line, column, text, "
                        "expected; or the rung list) for editors and CI")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.format or args.in_place:
        return _format(args)
    try:  # the devices too: a wrong device option is a configuration error like the rest
        plc = load_plc(args)
    except ProgramError as e:
        if args.json:
            print(json.dumps({"ok": False, "errors": [asdict(d) for d in e.diagnostics]},
                             indent=2))
            return 1
        return _report(e)
    except SoftPLCError as e:  # a missing file, a configuration error
        if not args.json:
            raise
        if isinstance(e, ConfigError) and args.config:  # one error per issue, with its code
            errors = [{**asdict(Diagnostic(i.message, str(args.config), text=i.path)),
                       "code": str(i.code)} for i in e.issues]
        else:
            errors = [asdict(Diagnostic(str(e), str(args.program)))]
        print(json.dumps({"ok": False, "errors": errors}, indent=2))
        return 1
    prog = plc.ast
    if args.json:
        print(json.dumps({"ok": True, "file": str(args.program), "rungs": [
            {"index": r.index, "title": r.title, "first_line": r.first_line,
             "last_line": r.last_line, "subroutine": r.subroutine, "label": r.label,
             "instructions": len(r.instructions)} for r in prog.rungs]}, indent=2))
        return 0
    kinds = Counter(type(i).__name__ for r in prog.rungs for i in r.instructions)
    n_instr = sum(kinds.values())
    subs = prog.subroutines
    print(f"{args.program}: OK - {_count(len(prog.rungs), 'rung')}, "
          f"{_count(n_instr, 'instruction')}"
          + (f", subroutines {', '.join(f'SR{n}' for n in subs)}" if subs else ""))
    if args.rungs:
        for r in prog.rungs:
            where = f"SR{r.subroutine}" if r.subroutine is not None else "main"
            label = f" %L{r.label}:" if r.label is not None else ""
            print(f"  rung {r.index:3d}  lines {r.first_line:4d}-{r.last_line:<4d} {where:5s}"
                  f"{label} {r.title}")
    if args.python:
        print(plc.program.source)
    return 0


def _report(e: ProgramError) -> int:
    for d in e.diagnostics:
        print(d, file=sys.stderr)
    print(_count(len(e.diagnostics), "error"), file=sys.stderr)
    return 1


def _format(args: argparse.Namespace) -> int:
    """The formatter: the program on stdout (or rewritten), every message on stderr."""
    from softplc.assembly import symbol_table
    from softplc.il.formatter import format_source

    if args.rungs or args.python or args.json:
        raise SoftPLCError("--format prints the program only: leave out --rungs, --python "
                           "and --json")
    check_files(args)
    raw = args.program.read_bytes()
    text = raw.decode("utf-8-sig", errors="replace")
    try:
        formatted = format_source(text, str(args.program), symbol_table(args.config)
                                  if args.config is not None else None)
        if args.config is not None:  # the full check too, blocks configured
            load_plc(args)
    except ProgramError as e:
        return _report(e)
    if not args.in_place:
        sys.stdout.write(formatted)
        return 0
    if b"\r\n" in raw:  # a TwidoSuite export from Windows stays CRLF
        formatted = formatted.replace("\n", "\r\n")
    if formatted.encode() == raw:
        print(f"{args.program}: already formatted", file=sys.stderr)
    else:
        args.program.write_bytes(formatted.encode())
        print(f"{args.program}: formatted", file=sys.stderr)
    return 0


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"
