"""`softplc replay PROGRAM.il CEX.json`: a counterexample of `softplc verify --cex` played
in the scan engine, as a table or (--web PORT) on the ladder with a scan slider."""

from __future__ import annotations

import argparse
import asyncio
from pathlib import Path
from typing import Any

from softplc.commands._args import add_program_arguments, check_files, existing_file, port
from softplc.errors import SoftPLCError

BANNER = ("REPLAY of a counterexample: the program runs only the trace's inputs (no Modbus "
          "server, no simulated plant, nothing written from outside); loopback only")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "replay", help="play a counterexample of softplc verify --cex, on the ladder",
        description="Run a counterexample's inputs scan by scan from a cold start in the "
                    "scan engine and show the requirement's objects in each scan: a table, "
                    "or with --web a page on 127.0.0.1 with the live ladder and a scan "
                    "slider (paused; step forward and back).")
    add_program_arguments(p)
    p.add_argument("cex", type=Path, metavar="CEX.json", help="written by softplc verify --cex")
    p.add_argument("--index", type=int, default=1, metavar="N",
                   help="which counterexample of the file, from 1 (default %(default)s)")
    p.add_argument("--web", type=port, metavar="PORT",
                   help="serve the replay page on 127.0.0.1:PORT (0 = any free port)")
    p.set_defaults(func=run)


def _player(args: argparse.Namespace) -> Any:
    from softplc.plc import PLC
    from softplc.verify.player import TracePlayer
    from softplc.verify.replay import read_cex

    check_files(args)
    items = read_cex(existing_file(args.cex, "counterexample"))["counterexamples"]
    if not 1 <= args.index <= len(items):
        raise SoftPLCError(f"--index {args.index}: {args.cex} holds counterexamples 1 to "
                           f"{len(items)}")
    return TracePlayer(lambda: PLC.from_file(args.program, config=args.config, devices=False),
                       items[args.index - 1])


def table(player: Any) -> str:
    """Each scan: its inputs, the requirement's objects in the engine, the status."""
    def row(r: dict[str, Any]) -> str:
        ins = " ".join(f"{k}={v}" for k, v in r["inputs"].items())
        vals = " ".join(f"{k}={v}" for k, v in r["values"].items())
        note = "" if r["agree"] else "  (the verifier's model differs)"
        return f"  scan {r['scan']:>4}: {ins} | {vals}  {r['status']}{note}"
    return "\n".join(row(r) for r in player.history())


def run(args: argparse.Namespace) -> int:
    player = _player(args)
    try:
        print(f"{args.program}: {player.requirement} ({player.check})")
        where = f"scan {player.violated_at}" if player.violated_at else "no scan"
        print(f"  {player.total} scan(s) from a cold start; violated in the engine at "
              f"{where} (reported: scan {player.total})")
        if args.web is None:
            print(table(player))
            return 0 if player.violated_at == player.total else 1
        return _serve(player, args)
    finally:
        player.close()


def _serve(player: Any, args: argparse.Namespace) -> int:
    from softplc.web.replay import ReplayServer

    async def main() -> None:
        server = ReplayServer(player, str(args.program), port=args.web)
        try:
            await server.start()
        except OSError as e:
            raise SoftPLCError(f"softplc replay: cannot listen on 127.0.0.1:{args.web}: "
                               f"{e.strerror or e}") from None
        print(BANNER)
        print(f"replay page on {server.url} (Ctrl-C to stop)", flush=True)
        try:
            await asyncio.Event().wait()
        finally:
            await server.close()
    try:
        asyncio.run(main())
    except KeyboardInterrupt:
        pass
    return 0
