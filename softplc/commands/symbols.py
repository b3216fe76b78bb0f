"""`softplc symbols import|export`: the symbol table between a configuration and a CSV file
in TwidoSuite's symbol layout (address, symbol, comment; softplc.twido.symbols).

    softplc symbols export --config motor.toml -o motor.csv   # [symbols] -> CSV
    softplc symbols import motor.csv                          # CSV -> [symbols] (stdout)
    softplc symbols import motor.csv --config motor.toml      # ... appended to the file
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from softplc.errors import ConfigError

_EXAMPLES = """\
examples:
  softplc symbols export --config motor.toml -o motor.csv
  softplc symbols export --config motor.toml --delimiter ';'
  softplc symbols import motor.csv                 # print a [symbols] section
  softplc symbols import motor.csv --config motor.toml   # append it to the file
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "symbols", help="import or export the symbol table (TwidoSuite CSV layout)",
        description="Symbols name addresses (START_PB for %I0.0) wherever an address may\n"
                    "stand: in the program, softplc io, the REPL, plc[\"START_PB\"]. They\n"
                    "are declared in the configuration ([symbols], or symbols_file = a CSV\n"
                    "of address, symbol, comment lines).",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    e = sub.add_parser("export", help="write the configuration's symbols as CSV")
    e.add_argument("--config", type=Path, required=True, metavar="FILE.toml",
                   help="the configuration declaring the symbols")
    e.add_argument("-o", "--output", type=Path, metavar="FILE.csv",
                   help="write there (default: stdout)")
    e.add_argument("--delimiter", default=",", choices=[",", ";", "tab"],
                   help="field separator (default ,)")
    e.set_defaults(func=run_export)
    i = sub.add_parser("import", help="read a CSV export into a [symbols] section")
    i.add_argument("csv", type=Path, metavar="FILE.csv",
                   help="address, symbol, comment a line (, ; or tab; a header is skipped)")
    i.add_argument("--config", type=Path, metavar="FILE.toml",
                   help="append the section to this configuration (default: print it)")
    i.set_defaults(func=run_import)


def run_export(args: argparse.Namespace) -> int:
    from softplc.assembly import symbol_table

    table = symbol_table(args.config)
    if not len(table):
        raise ConfigError(f"{args.config}: no symbols ([symbols] or symbols_file)")
    text = table.to_csv("\t" if args.delimiter == "tab" else args.delimiter)
    if args.output is None:
        sys.stdout.write(text)
    else:
        args.output.write_text(text, encoding="utf-8", newline="")
        print(f"{args.output}: {len(table)} symbols", file=sys.stderr)
    return 0


def run_import(args: argparse.Namespace) -> int:
    from softplc.assembly import load
    from softplc.config import Config, read_config
    from softplc.twido.profile import PROFILES
    from softplc.twido.symbols import SymbolTable, read_csv_file

    settings = load(args.config).settings if args.config is not None else Config()
    table = SymbolTable(read_csv_file(args.csv), PROFILES[settings.profile])  # checked
    section = table.to_toml()
    if args.config is None:
        sys.stdout.write(section)
        return 0
    if settings.symbols or settings.symbols_file:
        raise ConfigError(f"{args.config} already declares symbols: merge by hand, or "
                          f"point symbols_file at {args.csv}")
    text = args.config.read_text(encoding="utf-8")
    sep = "" if not text or text.endswith("\n\n") else ("\n" if text.endswith("\n") else "\n\n")
    args.config.write_text(text + sep + section, encoding="utf-8")
    read_config(args.config)  # still valid TOML
    print(f"{args.config}: {len(table)} symbols added from {args.csv}", file=sys.stderr)
    return 0
