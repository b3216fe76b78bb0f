"""`softplc load PROGRAM.il [--config X]`: change the program of a running daemon (online
change through its web API, `POST /api/program`).

The daemon checks and compiles the program; on an error nothing changes and every error is
printed with line:col. A configuration given with --config goes with the files it names
(its `symbols_file`, read here, relative to its folder): the daemon reads no file a request
names (`softplc.config.files`). What cannot carry over (a block removed, a preset changed) is listed
and asked about (unless --yes); the swap is made between two scans, keeping %M, %MW,
timers, counters and steps wherever the objects still exist.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from softplc.commands._args import CONFIG_HELP, existing_file, port
from softplc.commands.io import DEFAULT_PORT, Client
from softplc.errors import ConfigCode, ConfigError, SoftPLCError

LOAD_TIMEOUT = 120.0  # s: checking a ~1 MB program takes a while
PENDING_POLL_S = 0.2  # s between two looks at a swap the daemon is still making


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


#: Configuration keys that name a file the daemon needs to read (sent with the request).
FILE_KEYS = ("symbols_file",)


def _files(config: Path, text: str) -> dict[str, str]:
    """The files `config` (its `text`) names, read here: name -> text."""
    import tomllib

    from softplc.config.files import Local
    from softplc.twido.symbols import decode_csv

    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        return {}  # the daemon says what is wrong with it, at line:col
    files, policy = {}, Local()
    for key in FILE_KEYS:
        name = raw.get(key)
        if not isinstance(name, str) or not name:
            continue
        try:
            data = policy.read(name, config.parent, key, "symbol file")
        except ConfigError as e:
            if e.issues[0].code == ConfigCode.FILE and not (config.parent / name).exists():
                continue  # not here: the daemon's running copy of that name, if it has one
            raise
        files[name] = decode_csv(data, name)
    return files


def _pending(client: Client, answer: dict[str, Any]) -> dict[str, Any]:
    """An answer "still being made" (202: the scan thread began the swap and has not ended
    it) followed until the program's version says it ended (softplc.web.program)."""
    if answer.get("applied") is not None:
        return answer
    end = time.monotonic() + LOAD_TIMEOUT
    while time.monotonic() < end:
        info = client.request("program")["info"]
        if info["version"] >= answer["version"]:
            return {"applied": True, "info": info}
        time.sleep(PENDING_POLL_S)
    raise SoftPLCError(f"the daemon began the swap and did not end it within "
                       f"{LOAD_TIMEOUT:g} s: {answer['error']}")


def run(args: argparse.Namespace) -> int:
    config = None if args.config is None else _read(args.config, "configuration")
    body = {"program": _read(args.program, "program"), "file": str(args.program),
            "config": config, "confirm": bool(args.yes), "cold": bool(args.cold),
            "files": {} if config is None else _files(args.config, config)}
    client = Client(args.host, args.port, args.token, timeout=LOAD_TIMEOUT)
    answer = _pending(client, client.request("program", body))
    if answer["applied"] is False:
        print("This change loses state:")
        for loss in answer["losses"]:
            print("  " + loss)
        if not _ask("Load it anyway? [y/N] "):
            print("not loaded: nothing changed (--yes loads it, --cold also "
                  "cold-starts)", file=sys.stderr)
            return 1
        answer = _pending(client, client.request("program", body | {"confirm": True}))
    info = answer["info"]
    print(f"loaded {args.program}: version {info['version']}, sha256 {info['hash']}, "
          f"at {info['loaded_at']}" + (" (cold restart)" if answer.get("cold") else ""))
    return 0
