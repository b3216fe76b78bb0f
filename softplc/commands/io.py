"""`softplc io`: operate a running daemon through its web API (the monitor's JSON API),
which is the daemon's access port (`softplc.access`) over HTTP: the same command names
(`Action`), typed values (bits 0/1, words int, floats float), the same checks.

    softplc io set %I0.0 1            # an input (applied at the next scan boundary)
    softplc io get %MW0:4 %TM0        # values of one scan
    softplc io force %I0.1 0 ; softplc io unforce %I0.1 ; softplc io unforce
    softplc io run | stop | cold | warm | status
"""

from __future__ import annotations

import argparse
import json
import os
import re
import urllib.error
import urllib.request
from typing import Any

from softplc.access.commands import ACTIONS
from softplc.commands._args import port
from softplc.errors import SoftPLCError

DEFAULT_PORT = 8020  # softplc.web.DEFAULT_WEB_PORT, without importing aiohttp here
TIMEOUT = 5.0
_IEC = re.compile(r"^(16|8|2)#([0-9A-Fa-f_]+)$")


class IoError(SoftPLCError):
    """The daemon refused a request or cannot be reached."""


def parse_value(text: str) -> int | float:
    """'1', '-5', '16#FF', '2#1010', '0x1F', '1.5' -> a number."""
    t = text.strip()
    m = _IEC.match(t)
    try:
        if m:
            return int(m[2].replace("_", ""), int(m[1]))
        try:
            return int(t, 0)
        except ValueError:
            return float(t)
    except ValueError:
        raise IoError(f"{text!r} is not a number (e.g. 1, -5, 16#FF, 2#1010, 1.5)") from None


class Client:
    """A small client of the web API (also used by the tests and tools)."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 token: str | None = None, timeout: float = TIMEOUT):
        h = f"[{host}]" if ":" in host else host
        self.base = f"http://{h}:{port}/api/"
        self.token = token
        self.timeout = timeout

    def request(self, path: str, body: Any = None) -> Any:
        headers = {"Content-Type": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(self.base + path, data=data, headers=headers,
                                     method="GET" if body is None else "POST")
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as r:
                return json.loads(r.read())
        except urllib.error.HTTPError as e:
            try:
                msg = json.loads(e.read()).get("error", e.reason)
            except (ValueError, AttributeError):
                msg = e.reason
            raise IoError(f"{msg} (HTTP {e.code})") from None
        except (urllib.error.URLError, OSError) as e:
            reason = getattr(e, "reason", e)
            raise IoError(f"no softplc web API at {self.base}: {reason} (is `softplc run` "
                          f"running with --web on that port?)") from None

    def get(self, *objects: str) -> dict[str, Any]:
        q = "&".join("obj=" + urllib.request.quote(o) for o in objects)
        return self.request("read?" + q)["values"]

    def set(self, obj: str, value: Any) -> list[str]:
        return self.request("write", {"object": obj, "value": value})["queued"]

    def force(self, obj: str, value: Any) -> list[str]:
        return self.request("force", {"object": obj, "value": value})["forced"]

    def unforce(self, obj: str | None = None) -> list[str]:
        return self.request("unforce", {} if obj is None else {"object": obj})["unforced"]

    def control(self, action: str) -> str:
        """Queue one of the port's control commands (`ACTIONS`: run, stop, cold, warm)."""
        if action not in ACTIONS:
            raise IoError(f"action {action!r}: one of {', '.join(ACTIONS)}")
        return self.request("control", {"action": action})["action"]

    def status(self) -> dict[str, Any]:
        return self.request("status")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "io", help="read, write, force and RUN/STOP a running daemon (web API)",
        description="Operate a running `softplc run` through its web API. Changes are "
                    "applied at the next scan boundary; reads return the values of one scan. "
                    "Examples: `softplc io set %I0.0 1`, `softplc io get %MW0:4 %TM0`, "
                    "`softplc io force %I0.1 0`, `softplc io unforce`, `softplc io stop`.")
    p.add_argument("--host", default="127.0.0.1", help="daemon's web host (127.0.0.1)")
    p.add_argument("--port", type=port, default=DEFAULT_PORT,
                   help=f"daemon's web port (--web of softplc run; default {DEFAULT_PORT})")
    p.add_argument("--token", default=os.environ.get("SOFTPLC_TOKEN"),
                   help="token for changes when the monitor is not on loopback "
                        "(default: $SOFTPLC_TOKEN)")
    p.add_argument("--json", action="store_true", help="print the API's JSON answer")
    p.add_argument("action", choices=["get", "set", "force", "unforce", *ACTIONS, "status"],
                   help="get OBJ..., set OBJ VALUE [OBJ VALUE...], force OBJ VALUE, "
                        "unforce [OBJ], run, stop, cold, warm, status")
    p.add_argument("args", nargs="*", help="objects (%%MW3, %%MW0:10, %%I0.0, %%TM0.P... or "
                                           "symbols: STARTS, STARTS:2, STAR_TIME.P) and "
                                           "values (1, -5, 16#FF, 2#101, 1.5)")
    p.set_defaults(func=run)


def _pairs(args: list[str], what: str) -> list[tuple[str, int | float]]:
    if not args or len(args) % 2:
        raise IoError(f"{what}: give OBJECT VALUE pairs, e.g. `softplc io {what} %MW3 5`")
    return [(args[k], parse_value(args[k + 1])) for k in range(0, len(args), 2)]


def _symbols(c: Client) -> Any:
    """The daemon's symbol table (GET /api/info), to name the objects read as the REPL
    does (softplc.twido.symbols: one way of naming); an empty one if it has none."""
    from softplc.twido.profile import PROFILES
    from softplc.twido.symbols import Symbol, SymbolTable

    info = c.request("info")
    profile = PROFILES.get(info.get("profile", ""))
    symbols = [Symbol(name, addr, comment)
               for addr, (name, comment) in (info.get("symbols") or {}).items()]
    try:
        return SymbolTable(symbols, *([profile] if profile else []))
    except SoftPLCError:  # a daemon of another version: its names are not shown
        return SymbolTable()


def _show(name: str, value: Any) -> str:
    """A value of the API's answer as `softplc repl` prints it (softplc.twido.display)."""
    from softplc.twido.address import parse_address
    from softplc.twido.display import format_value

    try:
        ref = parse_address(name)
    except SoftPLCError:
        ref = None
    return format_value(value, ref)


def run(args: argparse.Namespace) -> int:
    c = Client(args.host, args.port, args.token)
    a, rest = args.action, args.args
    if a == "get":
        if not rest:
            raise IoError("get: name at least one object, e.g. `softplc io get %MW0:4`")
        out: Any = c.get(*rest)
        table = _symbols(c)  # each object with its symbol: `%Q0.0 KM1_MAIN = 1`
        lines = [f"{k}{' ' + n if (n := table.name_of(ref)) else ''} = {_show(k, v)}"
                 for k, v in out.items() for ref in [table.ref(k)]]
    elif a in ("set", "force"):
        if a == "set":
            out = c.request("write", {"writes": [{"object": o, "value": v}
                                                 for o, v in _pairs(rest, a)]})
            lines = [f"{o}: queued" for o in out["queued"]]
        else:
            out = [o for obj, v in _pairs(rest, a) for o in c.force(obj, v)]
            lines = [f"{o}: forced" for o in out]
    elif a == "unforce":
        if len(rest) > 1:
            raise IoError("unforce: one object, or none for all")
        out = c.unforce(rest[0] if rest else None)
        lines = [f"{o}: unforced" for o in out] or ["nothing was forced"]
    elif a == "status":
        out = c.status()
        lines = [f"{k}: {v}" for k, v in out.items()]
    else:
        if rest:
            raise IoError(f"{a} takes no arguments")
        out = c.control(a)
        lines = [f"{a}: queued (applied at the next scan boundary)"]
    print(json.dumps(out, indent=1) if args.json else "\n".join(lines))
    return 0
