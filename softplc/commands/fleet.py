"""`softplc fleet PROGRAM.il[,CONFIG.toml] ... --count N`: N soft Twidos served from one
process, each on its own Modbus TCP port (softplc.fleet)."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path

from softplc.commands._args import port
from softplc.commands.run import _duration, _period, _whole
from softplc.errors import SoftPLCError


def _program(text: str) -> tuple[Path, Path | None]:
    program, _, config = text.partition(",")
    return Path(program), Path(config) if config else None


def _ports(text: str) -> list[int]:
    return [port(p) for p in text.split(",") if p.strip()]


# softplc.fleet.MAX_CONTROLLERS, repeated so that `softplc --help` need not import the fleet
# (tests/e2e/test_check_command.py checks that the two agree)
MAX_CONTROLLERS = 1000


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fleet", help="serve many soft Twidos from one process, one Modbus port each",
        description="Run COUNT controllers in one process, each cold started with its "
                    "program and configuration (the programs are taken in turn) and served "
                    "on its own Modbus TCP port: a SCADA, HMI or Modbus scanner tested "
                    "against a hundred controllers on one machine. Stop with Ctrl-C.",
        epilog="example: softplc fleet ladder_programs/plant/station.il,"
               "ladder_programs/plant/filler.toml --count 100 --base-port 5100")
    p.add_argument("programs", nargs="+", type=_program, metavar="PROGRAM.il[,CONFIG.toml]",
                   help="a program and, after a comma, its configuration")
    p.add_argument("--count", type=_whole(1, MAX_CONTROLLERS), default=None,
                   help=f"controllers (1..{MAX_CONTROLLERS}; default: one per program)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address every port listens on (default 127.0.0.1)")
    p.add_argument("--base-port", type=port, default=5100,
                   help="the first controller's port, the others the next ones (default "
                        "5100; 0 = any free port each)")
    p.add_argument("--ports", type=_ports, metavar="P1,P2,...",
                   help="each controller's port, instead of --base-port")
    p.add_argument("--period", type=_period,
                   help="scan period of every controller (default: each configuration's "
                        "scan_period, or 10ms)")
    p.add_argument("--for", dest="duration", type=_duration, metavar="DURATION",
                   help="stop after this long (default: until Ctrl-C)")
    p.add_argument("--max-clients", type=_whole(1, 1000), default=4,
                   help="simultaneous Modbus connections per controller (default 4)")
    p.add_argument("--rt-priority", type=_whole(0, 99), default=10,
                   help="SCHED_FIFO priority of the scan thread, the Modbus thread one "
                        "below (default 10, as softplc run; 0 = normal scheduling); needs "
                        "root or CAP_SYS_NICE, else ignored")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from softplc.fleet import Fleet, members

    count = args.count or len(args.programs)
    if args.ports:
        ports = args.ports
    elif args.base_port:
        ports = list(range(args.base_port, args.base_port + count))
    else:
        ports = [0] * count
    if ports and ports[-1] > 0xFFFF:
        raise SoftPLCError(f"--base-port: {count} ports from {ports[0]} go past 65535")
    fleet = Fleet(members(args.programs, count, ports), args.host, period=args.period,
                  rt_priority=args.rt_priority, max_clients=args.max_clients)
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, lambda *_: fleet.stop())
    fleet.run(args.duration)
    fleet.say(fleet.summary())
    return 0
