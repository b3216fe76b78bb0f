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


def _player(args: argparse.Namespace, cex: Path, index: int) -> Any:
    from softplc.plc import PLC
    from softplc.verify.player import TracePlayer
    from softplc.verify.replay import read_cex

    check_files(args)
    items = read_cex(existing_file(cex, "counterexample"))["counterexamples"]
    if not 1 <= index <= len(items):
        raise SoftPLCError(f"--index {index}: {cex} holds counterexamples 1 to {len(items)}")
    return TracePlayer(lambda: PLC.from_file(args.program, config=args.config, devices=False),
                       items[index - 1])


def table(player: Any) -> str:
    """Each scan: its inputs, the requirement's objects in the engine, the status."""
    def row(r: dict[str, Any]) -> str:
        ins = " ".join(f"{k}={v}" for k, v in r["inputs"].items())
        vals = " ".join(f"{k}={v}" for k, v in r["values"].items())
        note = "" if r["agree"] else "  (the verifier's model differs)"
        return f"  scan {r['scan']:>4}: {ins} | {vals}  {r['status']}{note}"
    return "\n".join(row(r) for r in player.history())


def run(args: argparse.Namespace) -> int:
    return play(args, args.cex, args.index, args.web)


def play(args: argparse.Namespace, cex: Path, index: int, web: int | None) -> int:
    """Replay counterexample `index` of `cex` on `args.program` and `args.config`: the
    table, or the page on 127.0.0.1:`web` (also `softplc run PROGRAM --replay CEX.json`)."""
    player = _player(args, cex, index)
    try:
        print(f"{args.program}: {player.requirement} ({player.check})")
        where = f"scan {player.violated_at}" if player.violated_at else "no scan"
        print(f"  {player.total} scan(s) from a cold start; violated in the engine at "
              f"{where} (reported: scan {player.total})")
        if web is None:
            print(table(player))
            return 0 if player.violated_at == player.total else 1
        return _serve(player, str(args.program), web)
    finally:
        player.close()


def _serve(player: Any, program: str, web: int) -> int:
    from softplc.web.replay import ReplayServer

    async def main() -> None:
        server = ReplayServer(player, program, port=web)
        try:
            await server.start()
        except OSError as e:
            raise SoftPLCError(f"softplc replay: cannot listen on 127.0.0.1:{web}: "
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
