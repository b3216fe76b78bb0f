"""`softplc run PROGRAM.il`: a soft Twido on the real clock that Modbus hosts can talk to.

Settings come from the command line, else from the machine config, else defaults:

    scan_period = "10ms"                 # --period
    [modbus]  host = "127.0.0.1"  port = 5020  max_clients = 32   # 1..1000
              frame_timeout = "2s"   # 0.1..60 s from a frame's first byte to its last
              idle_timeout = "60s"   # 1 s..1 day without a complete request; "0s" = never
              read_only = ["%MW100:20", "%M0:8"]             # writes there get exception 02
              allow = ["127.0.0.1", "192.168.1.0/24"]        # --allow; default: anyone
    [daemon]  state = "plc.state"  save_interval = "5s"  stats_interval = "60s"
              rt_priority = 10                               # 0 = normal scheduling
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import re
from pathlib import Path
from typing import Any

from softplc.commands._args import add_program_arguments, load_plc, port
from softplc.errors import ConfigError

# the tokens kept out of the command line (`ps`): `plant up` gives them so
WEB_TOKEN_ENV, WEB_READ_TOKEN_ENV = "SOFTPLC_WEB_TOKEN", "SOFTPLC_WEB_READ_TOKEN"
_BARE_NUMBER = re.compile(r"^\s*[0-9]*\.?[0-9]+\s*$")


def _duration(text: str, bare_unit: str = "s") -> float:
    from softplc.config import (
        duration,  # pydantic: imported when a duration is given, not for --help
    )

    if _BARE_NUMBER.match(text):
        text += bare_unit
    try:
        return duration(text)
    except ConfigError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _checked(check_name: str) -> Any:
    """An argparse type: a duration (bare number = seconds) passed through the config's
    bound check `check_name` (softplc.config), so the flag and the key take the same values."""
    def parse(text: str) -> float:
        from softplc import config

        v = _duration(text)
        try:
            return getattr(config, check_name)(v)
        except ValueError as e:
            raise argparse.ArgumentTypeError(f"{text!r}: {e}") from None
    return parse


def _whole(lo: int, hi: int) -> Any:
    """An argparse type: a whole number lo..hi (the bounds of the configuration key)."""
    def parse(text: str) -> int:
        if not text.strip().isdigit() or not lo <= int(text) <= hi:
            raise argparse.ArgumentTypeError(f"{text!r}: a whole number from {lo} to {hi}")
        return int(text)
    return parse


def _max_clients(text: str) -> int:
    from softplc.config import MAX_CLIENTS

    return _whole(1, MAX_CLIENTS)(text)


def _interval(text: str) -> float:
    """--save-interval, --stats-interval: a duration, 0 (off) or at least 10 ms."""
    from softplc.config import check_interval

    try:
        return check_interval(_duration(text))
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"{text!r}: {e}") from None


def _period(text: str) -> float:
    return _duration(text, "ms")


def _speed(text: str) -> float:
    if text.strip().lower() == "max":
        return math.inf
    try:
        v = float(text)
    except ValueError:
        v = -1.0
    if not 0 < v < math.inf:
        raise argparse.ArgumentTypeError(f"bad speed {text!r}: a positive factor or 'max'")
    return v


_WEB_OFF = -1


def _web_port(text: str) -> int:
    return _WEB_OFF if text.strip().lower() == "off" else port(text)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "run", help="run a program with a Modbus TCP server (a soft Twido)",
        description="Run PROGRAM.il periodically on the real clock and serve its memory over "
                    "Modbus TCP: %MWn = holding/input register n (functions 3/4/6/16/23), %Mn = "
                    "coil/discrete input n (functions 1/2/5/15), function 43/14 device "
                    "identification. "
                    "Host writes are applied at the start of the next scan; reads return the "
                    "image of the last scan with the writes acknowledged since. Stop with "
                    "Ctrl-C or SIGTERM: the scan finishes, outputs go to 0, the state file is "
                    "saved.")
    add_program_arguments(p)
    p.add_argument("--host", help="address to listen on (default 127.0.0.1; 'localhost' = "
                                  "127.0.0.1 and ::1; 0.0.0.0 for all IPv4)")
    p.add_argument("--port", type=port,
                   help="TCP port (default 5020; a real Twido uses 502; 0 = any free port)")
    p.add_argument("--period", type=_period,
                   help="scan period = %%SW0, whole ms (default: config scan_period, or 10ms)")
    p.add_argument("--state", type=Path,
                   help="retained-state file: warm restart from it, saved periodically and "
                        "at shutdown")
    p.add_argument("--state-symlink", action="store_true",
                   help="allow a --state that is a symbolic link (refused by default: a "
                        "cold start would overwrite the file it points to)")
    p.add_argument("--cold", action="store_true",
                   help="cold start even if the state file holds data (or is damaged)")
    p.add_argument("--keep-state", action="store_true",
                   help="run PROGRAM.il warm with the state file's data even if that data "
                        "belongs to another program or configuration (default: the start "
                        "stops and says what differs)")
    p.add_argument("--program-from-state", action="store_true",
                   help="run the program kept with the state file's data (the last one "
                        "loaded online, or run), whatever PROGRAM.il holds; by default it "
                        "runs when PROGRAM.il is the program it replaced, and a PROGRAM.il "
                        "that differs otherwise stops the start until you choose")
    p.add_argument("--save-interval", type=_interval,
                   help="how often to flush the state file to disk, for power loss (default "
                        "5s; 0 = only at shutdown); a killed process loses nothing anyway")
    p.add_argument("--speed", type=_speed, default=None,
                   help="virtual clock N times faster than real time, or 'max'")
    p.add_argument("--no-host-wait", action="store_true",
                   help="with --speed, run the virtual clock on while the program waits for "
                        "its host (ignore the config's [daemon] host_wait bit)")
    p.add_argument("--stats-interval", type=_interval,
                   help="statistics line every ... (default 60s; 0 = none); "
                        "SIGUSR1 prints one at once")
    p.add_argument("--max-clients", type=_max_clients,
                   help="simultaneous Modbus connections (32, up to 1000); when all "
                        "are taken a new client takes the slot of an unused one")
    p.add_argument("--idle-timeout", type=_checked("idle_timeout_ok"), metavar="DURATION",
                   help="close a Modbus client that completes no request for this long "
                        "(default 60s; 0 = never)")
    p.add_argument("--frame-timeout", type=_checked("frame_timeout_ok"), metavar="DURATION",
                   help="close a Modbus client whose frame is not complete this long after "
                        "its first byte (default 2s)")
    p.add_argument("--read-only", action="store_true",
                   help="refuse every Modbus write (exception 01, illegal function)")
    p.add_argument("--allow", action="append", metavar="ADDR[/NET],...",
                   help="accept clients only from these addresses or networks (IPv4/IPv6, "
                        "comma-separated, repeatable); others are disconnected before any "
                        "byte is read")
    p.add_argument("--rt-priority", type=_whole(0, 99),
                   help="SCHED_FIFO priority of the scan thread, 1..99, the Modbus thread "
                        "one below (default 10; 0 = normal scheduling); needs root or "
                        "CAP_SYS_NICE, else ignored")
    p.add_argument("--no-gc-freeze", action="store_true",
                   help="do not freeze the objects made at start-up out of the garbage "
                        "collector's reach (comparisons: tools/bench_gc.py)")
    p.add_argument("--trace", type=Path, metavar="FILE.csv",
                   help="keep the machine's trace recorder's samples (t,x,z,pen,missed) in "
                        "this CSV file (flushed every simulated second and at shutdown)")
    p.add_argument("--config-dir", type=Path, metavar="DIR",
                   help="an online change's configuration may name files (symbols_file) "
                        "under DIR, regular files only (default: none; the files go with "
                        "the request, as `softplc load` sends them)")
    # the Remote Link over TCP (softplc.runtime.linktcp)
    p.add_argument("--link-listen", type=_endpoint, metavar="HOST:PORT",
                   help="a remote of the Remote Link ([remote_link] address 1..7): answer "
                        "the master's polls on this TCP address (port 0 = any free port)")
    p.add_argument("--link-remote", action="append", default=[], type=_link_remote,
                   metavar="ADDR=HOST:PORT",
                   help="the master ([remote_link] address 0): where remote ADDR listens; "
                        "one for each declared remote (repeatable)")
    # hardwired signals from the plant host (softplc.access.wires)
    p.add_argument("--wire-listen", type=_endpoint, metavar="HOST:PORT",
                   help="take the wired inputs from the plant host (`softplc plant "
                        "process`) and give it the wired outputs on this TCP address")
    p.add_argument("--wire-peer", metavar="ADDR",
                   help="with --wire-listen: the plant host's address, the only one that "
                        "may connect")
    p.add_argument("--wire-in", default="", metavar="%I0.0,...",
                   help="with --wire-listen: the inputs the plant host drives, in order "
                        "(written at scan boundaries; 0 when the plant host is gone)")
    p.add_argument("--wire-out", default="", metavar="%Q0.0,...",
                   help="with --wire-listen: the outputs the plant host reads, in order")
    # web monitor options (softplc.web)
    p.add_argument("--web", type=_web_port, default=None, metavar="PORT|off",
                   help="web monitor port (default 8020, on 127.0.0.1; 0 = any free port; "
                        "off = no web monitor)")
    p.add_argument("--web-host", default="127.0.0.1",
                   help="address of the web monitor (default 127.0.0.1); on any other "
                        "address every request needs the token printed at start")
    p.add_argument("--web-read-only", action="store_true",
                   help="the web monitor and its API only show: no writes, forcing, RUN/STOP")
    p.add_argument("--web-token", default=os.environ.get(WEB_TOKEN_ENV),
                   help="token for changes through the web API; beyond loopback for every "
                        f"request (default: ${WEB_TOKEN_ENV}, else a random one there)")
    p.add_argument("--web-read-token", metavar="TOKEN",
                   default=os.environ.get(WEB_READ_TOKEN_ENV),
                   help="beyond loopback, a second token that only reads (page, API, "
                        f"websocket; default: ${WEB_READ_TOKEN_ENV})")
    p.add_argument("--web-allow-host", action="append", default=[], metavar="NAME,...",
                   help="a Host name the monitor answers to besides localhost, this "
                        "machine's name and IP addresses (repeatable; * = any; or [web] "
                        "allowed_hosts)")
    p.add_argument("--web-max-pages", type=_whole(1, 1000), default=None, metavar="N",
                   help="websocket pages open at once, 1..1000 (default 32, or [web] "
                        "max_pages)")
    p.add_argument("--replay", type=Path, metavar="CEX.json",
                   help="play a counterexample of softplc verify --cex instead (as softplc "
                        "replay): no Modbus server, no devices, nothing written from "
                        "outside; its page on the --web port, on 127.0.0.1 only")
    p.add_argument("--log-level", default="warning",
                   choices=["debug", "info", "warning", "error"],
                   help="level of server log messages on stderr (default warning)")
    p.set_defaults(func=run)
    # what --replay leaves unused: refused when given, never silently ignored
    _DAEMON_DEFAULTS.update({a.dest: a.default for a in p._actions
                             if a.option_strings and a.dest not in _REPLAY_USES})


# The options a replay uses (the rest belong to the daemon it replaces: refused with it).
_REPLAY_USES = {"help", "config", "replay", "web", "log_level", "symbols"}
_DAEMON_DEFAULTS: dict[str, Any] = {}


def _replay_refuses(args: argparse.Namespace) -> None:
    given = sorted(f"--{d.replace('_', '-')}" for d, default in _DAEMON_DEFAULTS.items()
                   if getattr(args, d, default) != default)
    if given:
        raise ConfigError(f"--replay plays a counterexample without a daemon: "
                          f"{', '.join(given)} would have no effect (drop them; the page "
                          f"is on 127.0.0.1 at the --web port)")


def _endpoint(text: str) -> tuple[str, int]:
    from softplc.runtime.linktcp import endpoint

    try:
        return endpoint(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _link_remote(text: str) -> tuple[int, tuple[str, int]]:
    from softplc.twido.address import LINK_STATIONS

    addr, sep, where = text.partition("=")
    if not sep or not addr.strip().isdigit() or not 1 <= int(addr) < LINK_STATIONS:
        raise argparse.ArgumentTypeError(
            f"{text!r}: write ADDR=HOST:PORT, ADDR a remote's address 1..{LINK_STATIONS - 1}")
    return int(addr), _endpoint(where)


def _link(args: argparse.Namespace, plc: Any) -> Any:
    """The Remote Link service --link-listen / --link-remote ask for, bound (None: none)."""
    from softplc.runtime import linktcp
    from softplc.runtime.remotelink import LinkMaster

    station = plc.machine.link
    if not args.link_listen and not args.link_remote:
        return None
    if station is None:
        raise ConfigError("--link-listen / --link-remote: the configuration has no "
                          "[remote_link] section")
    if isinstance(station, LinkMaster):
        if args.link_listen:
            raise ConfigError("--link-listen is a remote's option; the master ([remote_link] "
                              "address 0) names its remotes with --link-remote")
        endpoints: dict[int, tuple[str, int]] = {}
        for a, where in args.link_remote:
            if a in endpoints:
                raise ConfigError(f"--link-remote: remote {a} given twice")
            endpoints[a] = where
        return linktcp.MasterService(station, endpoints)
    if args.link_remote or not args.link_listen:
        raise ConfigError(f"remote {station.address} of the Remote Link: --link-listen "
                          f"HOST:PORT (--link-remote is the master's)")
    return linktcp.RemoteService(station, *args.link_listen)


def _wires(args: argparse.Namespace) -> Any:
    """The wire service --wire-listen asks for, bound (None: none)."""
    given = args.wire_peer or args.wire_in or args.wire_out
    if not args.wire_listen:
        if given:
            raise ConfigError("--wire-peer / --wire-in / --wire-out go with --wire-listen")
        return None
    if not args.wire_peer:
        raise ConfigError("--wire-listen: --wire-peer ADDR names the plant host, the only "
                          "address that may drive the wired inputs")
    from softplc.access.wires import WireService

    def names(text: str) -> list[str]:
        return [n.strip() for n in text.split(",") if n.strip()]
    try:
        return WireService(*args.wire_listen, args.wire_peer, names(args.wire_in),
                           names(args.wire_out))
    except ValueError as e:
        raise ConfigError(str(e)) from None


def _pick(cli: Any, configured: Any) -> Any:
    """The command-line value if given, else the configuration's (validated, defaulted)."""
    return configured if cli is None else cli


_LOCKED: list[int] = []  # descriptors held open (and locked) until the process ends


def run(args: argparse.Namespace) -> int:
    if args.replay is not None:
        from softplc.commands.replay import play

        _replay_refuses(args)
        from softplc.web import DEFAULT_WEB_PORT

        web = None if args.web == _WEB_OFF else _pick(args.web, DEFAULT_WEB_PORT)
        return play(args, args.replay, 1, web)
    from softplc.daemon import Daemon, DaemonOptions

    logging.basicConfig(level=getattr(logging, args.log_level.upper()),
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    from softplc.assembly import application_id
    from softplc.modbus.server import parse_allow
    from softplc.persist.retain import open_locked

    plc = load_plc(args, clock="real" if args.speed is None else "virtual")
    outputs = []
    waits: list[Any] = []
    if args.trace is not None:
        recorder = next((d for d in plc.devices.values()
                         if getattr(d, "type_name", "") == "trace"), None)
        if recorder is None:
            raise ConfigError("--trace: the machine config has no trace device")
        trace = args.trace

        def open_trace() -> None:
            trace.parent.mkdir(parents=True, exist_ok=True)
            # locked for the process' life before record_to truncates it
            _LOCKED.append(open_locked(trace, "trace file"))
            recorder.record_to(trace)
        outputs.append(open_trace)
        waits.append(recorder.flush)  # the host reads the file while the clock is held
    mb, dm = plc.settings.modbus, plc.settings.daemon  # checked by the configuration schema
    period = _pick(args.period, plc.settings.scan_period)
    state = Path(dm.state) if args.state is None and dm.state is not None else args.state
    base = plc.config_dir
    if args.state is None and state is not None and base is not None and not state.is_absolute():
        state = base / state  # a path in the config is relative to the config file
    allow = None
    if args.allow:
        allow = parse_allow(a for arg in args.allow for a in arg.split(",") if a.strip())
    elif mb.allow is not None:
        allow = parse_allow([mb.allow] if isinstance(mb.allow, str) else mb.allow)
    opts = DaemonOptions(
        host=_pick(args.host, mb.host),
        port=_pick(args.port, mb.port),
        period=period,
        state=state,
        state_symlink=args.state_symlink,
        cold=args.cold,
        keep_state=args.keep_state,
        program_from_state=args.program_from_state,
        save_interval=_pick(args.save_interval, dm.save_interval),
        speed=args.speed,
        stats_interval=_pick(args.stats_interval, dm.stats_interval),
        max_clients=_pick(args.max_clients, mb.max_clients),
        frame_timeout=_pick(args.frame_timeout, mb.frame_timeout),
        idle_timeout=_pick(args.idle_timeout, mb.idle_timeout) or None,
        rt_priority=_pick(args.rt_priority, dm.rt_priority),
        host_wait=None if args.no_host_wait else dm.host_wait_bit,
        read_only=args.read_only,
        allow=allow,
        open_outputs=outputs,
        on_host_wait=waits,
        web=_web_options(args, plc.settings.web),
        gc_freeze=not args.no_gc_freeze,
        config_dir=_folder(args.config_dir),
        link=_link(args, plc),
        wires=_wires(args),
    )
    app = application_id(plc.machine, args.program.read_bytes())
    return Daemon(plc, opts, program_name=str(args.program), app=app).run()


def _folder(path: Path | None) -> Path | None:
    """--config-dir checked: an existing folder, resolved (links included) once, here."""
    if path is None:
        return None
    if not path.is_dir():
        raise ConfigError(f"--config-dir {path}: not a folder")
    return path.resolve()


def _web_options(args: argparse.Namespace, configured: Any) -> Any:
    """The web monitor's options (softplc.web), from the --web-* options, else the
    configuration's [web] (`configured`, validated)."""
    from softplc.web import DEFAULT_WEB_PORT, WebOptions

    if args.web == _WEB_OFF:
        return None
    pages = _pick(args.web_max_pages, configured.max_pages)
    hosts = [h for arg in args.web_allow_host for h in arg.split(",")] \
        or configured.allowed_hosts
    return WebOptions(port=DEFAULT_WEB_PORT if args.web is None else args.web,
                      host=args.web_host, read_only=args.web_read_only,
                      token=args.web_token, port_given=args.web is not None,
                      read_token=args.web_read_token, max_pages=pages,
                      allowed_hosts=tuple(h.strip() for h in hosts if h.strip()))
