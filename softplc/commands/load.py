"""`softplc load PROGRAM.il [--config X]`: change the program of a running daemon (online
change through its web API, `POST /api/program`).

The daemon checks and compiles the program; on an error nothing changes and every error is
printed with line:col. What cannot carry over (a block removed, a preset changed) is listed
and asked about (unless --yes); the swap is made between two scans, keeping %M, %MW,
timers, counters and steps wherever the objects still exist.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from softplc.commands._args import CONFIG_HELP, existing_file, port
from softplc.commands.io import DEFAULT_PORT, Client
from softplc.errors import SoftPLCError

LOAD_TIMEOUT = 120.0  # s: checking a ~1 MB program takes a while


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "load", help="change the program of a running daemon (online change)",
        description="Send PROGRAM.il (and a new configuration, or keep the running one) "
                    "to a running `softplc run` through its web API. It is checked first: "
                    "on an error nothing changes. What cannot carry over is listed and "
                    "asked about; the swap keeps memory, timers and counters.",
        epilog="example: softplc load ladder_programs/star_delta.il --port 8020")
    p.add_argument("program", type=Path, metavar="PROGRAM.il", help="the new program")
    p.add_argument("--config", type=Path, metavar="FILE.toml",
                   help="new configuration (default: keep the running one); "
                        + CONFIG_HELP.split(": ")[1])
    p.add_argument("--host", default="127.0.0.1", help="daemon's web host (127.0.0.1)")
    p.add_argument("--port", type=port, default=DEFAULT_PORT,
                   help=f"daemon's web port (--web of softplc run; default {DEFAULT_PORT})")
    p.add_argument("--token", default=os.environ.get("SOFTPLC_TOKEN"),
                   help="the web token, if the daemon has one (default: $SOFTPLC_TOKEN)")
    p.add_argument("--yes", "-y", action="store_true",
                   help="load even if some state is lost, without asking")
    p.add_argument("--cold", action="store_true",
                   help="cold restart after the change (reset %%M, %%MW, blocks)")
    p.set_defaults(func=run)


def _read(path: Path, what: str) -> str:
    existing_file(path, what)
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise SoftPLCError(f"{path}: cannot read the {what}: {e}") from None


def _ask(question: str) -> bool:
    try:  # no one to answer (stdin closed): no
        return input(question).strip().lower() in ("y", "yes")
    except EOFError:
        return False


def run(args: argparse.Namespace) -> int:
    body = {"program": _read(args.program, "program"), "file": str(args.program),
            "config": None if args.config is None else _read(args.config, "configuration"),
            "confirm": bool(args.yes), "cold": bool(args.cold)}
    client = Client(args.host, args.port, args.token, timeout=LOAD_TIMEOUT)
    answer = client.request("program", body)
    if not answer["applied"]:
        print("This change loses state:")
        for loss in answer["losses"]:
            print("  " + loss)
        if not _ask("Load it anyway? [y/N] "):
            print("not loaded: nothing changed (--yes loads it, --cold also "
                  "cold-starts)", file=sys.stderr)
            return 1
        answer = client.request("program", body | {"confirm": True})
    info = answer["info"]
    print(f"loaded {args.program}: version {info['version']}, sha256 {info['hash']}, "
          f"at {info['loaded_at']}" + (" (cold restart)" if answer.get("cold") else ""))
    return 0
