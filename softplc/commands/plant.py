"""`softplc plant`: a plant of soft Twidos (issue 35).

    softplc plant check plant.toml                 # load and build; every error, with its line
    softplc plant run plant.toml [--speed max] [--for 60s] [--set master:%I0.0=1]
                                 [--print master:%MW0] [--every 10s] [--json]
    softplc plant up plant.toml --netns [--web PORT|off]   # each controller a daemon, its
                                                   # own host; the plant page on PORT
    softplc plant down plant.toml                  # stop them, remove the namespaces
    softplc plant process plant.toml               # the shared devices and wires, their
                                                   # I/O over TCP (`up` starts it)
    softplc plant page plant.toml --record FILE    # the page of a plant that is up (`up`
                                                   # starts it)

`run` runs every controller, link, wire and shared device of the plant file in this
process on one virtual clock (softplc.plant): the same result on every run. `--speed N`
paces plant time at N times real time (default 1), `max` as fast as it goes.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from softplc.commands._args import port
from softplc.commands.run import _speed
from softplc.errors import PlantStateError

if TYPE_CHECKING:  # imported when the command runs: `softplc --help` stays light
    from softplc.plant import Plant

STATE_DIR = Path(tempfile.gettempdir()) / "softplc-plants"  # `plant up` records and logs
PUBLISH_S = 0.1  # how often (real time) the plant page gets a new view
PACE_SLICE_S = 0.05  # longest sleep while pacing: Ctrl-C stays prompt


def _duration(text: str) -> float:
    from softplc.config.fields import _parse_duration

    try:
        return _parse_duration(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"{text!r}: {e}") from None


def _assignment(text: str) -> tuple[str, int | float]:
    from softplc.debug.registry import parse_value

    key, sep, value = text.partition("=")
    if not sep or ":" not in key:
        raise argparse.ArgumentTypeError(f"{text!r}: write CONTROLLER:%ADDRESS=VALUE")
    try:
        return key.strip(), parse_value(value)
    except Exception:  # the debugger's parser says what it takes
        raise argparse.ArgumentTypeError(f"{text!r}: {value!r} is not a number") from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plant", help="run several controllers, their links, wires and "
                                     "shared devices from a plant file",
                       description="A plant of soft Twidos (plant.toml): the controllers, "
                                   "their Remote Links, wires and shared devices.")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    c = verbs.add_parser("check", help="load and build a plant; print every error")
    c.add_argument("plant", help="the plant file (plant.toml)")
    c.set_defaults(func=_check)
    r = verbs.add_parser("run", help="run the plant in this process on one virtual clock")
    r.add_argument("plant", help="the plant file (plant.toml)")
    r.add_argument("--speed", type=_speed, default=1.0,
                   help="plant time N times faster than real time, or 'max' (default 1)")
    r.add_argument("--for", dest="duration", type=_duration, default=None, metavar="TIME",
                   help="stop after this much plant time (e.g. 60s, 5min); default: Ctrl-C")
    r.add_argument("--set", action="append", type=_assignment, default=[],
                   metavar="CTL:%ADDR=V", help="write an object before the start (repeat)")
    r.add_argument("--print", dest="show", action="append", default=[], metavar="CTL:%ADDR",
                   help="an object (or DEVICE:SIGNAL) to print with each status (repeat)")
    r.add_argument("--every", type=_duration, default=None, metavar="TIME",
                   help="print the status every TIME of plant time (default: at the end)")
    r.add_argument("--json", action="store_true", help="print the status as JSON lines")
    r.add_argument("--web", type=port, default=None, metavar="PORT",
                   help="serve the plant page on 127.0.0.1:PORT (0 = any free port): each "
                        "controller's state, scans, scan time, link health and words")
    r.set_defaults(func=_run)
    u = verbs.add_parser("up", help="each controller a `softplc run` daemon in its own "
                                    "network namespace, the Remote Link over TCP")
    u.add_argument("plant", help="the plant file (plant.toml)")
    u.add_argument("--netns", action="store_true", required=True,
                   help="network namespaces, a bridge and veth pairs (iproute2; root)")
    u.add_argument("--state-dir", type=Path, default=STATE_DIR,
                   help=f"where the record of what was made and the logs go "
                        f"(default {STATE_DIR})")
    u.add_argument("--web", type=_page_port, default=None, metavar="PORT|off",
                   help="the plant page on 127.0.0.1:PORT of this machine (default 8030; 0 = "
                        "any free port) and each controller's web monitor on its own "
                        "address; off = neither")
    u.set_defaults(func=_up)
    g = verbs.add_parser("page", help="the plant page of a plant that is up (`plant up` "
                                      "starts it)")
    g.add_argument("plant", help="the plant file (plant.toml)")
    g.add_argument("--record", type=Path, required=True,
                   help="`plant up`'s record (spTAG.json in its state folder)")
    g.add_argument("--port", type=port, default=0, help="on 127.0.0.1 (0 = any free port)")
    g.set_defaults(func=_page)
    h = verbs.add_parser("process", help="the plant's shared devices and wires on the real "
                                         "clock, the controllers' wired I/O over TCP "
                                         "(the plant host `plant up` starts)")
    h.add_argument("plant", help="the plant file (plant.toml)")
    h.add_argument("--port", type=port, default=None,
                   help="the controllers' --wire-listen port (default: plant up's)")
    h.add_argument("--for", dest="duration", type=_duration, default=None, metavar="TIME",
                   help="stop after this much time (default: SIGTERM or Ctrl-C)")
    h.set_defaults(func=_process)
    d = verbs.add_parser("down", help="stop the daemons and remove the namespaces "
                                      "`plant up` made")
    d.add_argument("plant", help="the plant file (plant.toml)")
    d.add_argument("--state-dir", type=Path, default=STATE_DIR,
                   help=f"the --state-dir of `plant up` (default {STATE_DIR})")
    d.set_defaults(func=_down)


_PAGE_OFF = -1
# what `softplc run` (with its web monitor and wires), `plant process` and `plant page`
# import (and every device type's module, `preload`): loaded once by `plant up`, shared by
# every daemon it forks
PRELOAD = ("softplc.cli", "softplc.commands.run", "softplc.daemon", "softplc.plc",
           "softplc.access.port", "softplc.access.wires", "softplc.web", "softplc.web.server",
           "softplc.plant.process", "softplc.runtime.linktcp", "softplc.commands.plantweb",
           "softplc.web.plantpage", "softplc.modbus.host")


def preload() -> None:
    """Import PRELOAD and build what each daemon would build at its start (the IL parser's
    tables, uvloop's module): once, in a process that forks daemons (`plant up`, the test
    suite's zygote). A forked daemon's start then costs about 0.05 CPU-s, not 0.25."""
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    from softplc.devices import device_types

    # a daemon imports its devices' modules when its configuration names them: here, once
    list(device_types().values())
    from softplc.il.parser import prepare
    from softplc.modbus.server import new_event_loop

    prepare()
    new_event_loop().close()


def _page_port(text: str) -> int:
    return _PAGE_OFF if text.strip().lower() == "off" else port(text)


def _page(args: argparse.Namespace) -> int:
    from softplc.commands.plantweb import serve

    return serve(args)


def _up(args: argparse.Namespace) -> int:
    from softplc.plant import hosts

    why = hosts.netns_works()
    if why:
        raise PlantStateError(f"plant up --netns: network namespaces do not work here: {why}")
    hosts.not_up(Path(args.plant), args.state_dir)  # refused before loading the plant

    from softplc.plant.model import load_plant

    spec = load_plant(args.plant)
    page = hosts.PAGE_PORT if args.web is None else None if args.web == _PAGE_OFF else args.web
    record = hosts.up(spec, args.state_dir, preload, page)
    print(f"{args.plant}: up; SCADA namespace {record['namespaces'][0]} at "
          f"{record['scada']}")
    for name, c in record["controllers"].items():
        print(f"  {name}: namespace {c['namespace']}, Modbus {c['host']}:{hosts.MODBUS_PORT}, "
              f"pid {c['pid']}, log {c['log']}")
    plant = record["processes"].get(hosts.PLANT)
    if plant is not None:
        print(f"  plant host (shared devices, wires): namespace {plant['namespace']}, "
              f"{plant['host']}, pid {plant['pid']}, log {plant['log']}")
    if record["root"]:
        print(f"  this machine: {record['root']} on the plant network ({record['root_veth']})")
        if record["page"]:
            print(f"plant page: {record['page']} (each controller's monitor: "
                  f"http://ADDRESS:{hosts.WEB_PORT}/, the token in {args.state_dir})")
    else:
        print("  this machine has an address in the plant's network already (another "
              "plant?): no veth to it; reach the controllers from the SCADA namespace")
    first = next(iter(record["controllers"].values()))["host"]
    if record["token"]:
        print(f"e.g. softplc io --host {first} --token TOKEN get %MW0 (TOKEN: \"token\" in "
              f"the record, {args.state_dir}/sp{hosts.tag(Path(args.plant))}.json)")
    print(f"Modbus: {first}:{hosts.MODBUS_PORT} ... from the SCADA namespace (ip netns exec "
          f"{record['namespaces'][0]} ...) or this machine; stop with: "
          f"softplc plant down {args.plant}")
    return 0


def _process(args: argparse.Namespace) -> int:
    import signal

    from softplc.plant import hosts
    from softplc.plant.model import load_plant
    from softplc.plant.process import WIRE_PORT, PhysicalProcess

    spec = load_plant(args.plant)
    addr = hosts.addresses(spec)
    proc = PhysicalProcess(spec, addr, WIRE_PORT if args.port is None else args.port)
    stopping: list[int] = []
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    to = ", ".join(f"{n} {c.where[0]}:{c.where[1]}" for n, c in proc.clients.items())
    print(f"{args.plant}: {len(proc.devices)} shared devices, {len(spec.wires)} wires, "
          f"wired controllers: {to or 'none'}", flush=True)
    print(f"plant process: ticking every {proc.tick_s * 1000:g} ms", flush=True)
    end = None if args.duration is None else time.monotonic() + args.duration
    try:
        proc.run(lambda: bool(stopping) or (end is not None and time.monotonic() >= end))
    except KeyboardInterrupt:
        pass
    finally:
        proc.close()
        print(json.dumps(proc.status()), flush=True)
    return 0


def _down(args: argparse.Namespace) -> int:
    from softplc.plant import hosts

    for line in hosts.down(hosts.record_path(Path(args.plant), args.state_dir)):
        print(line)
    return 0


def _check(args: argparse.Namespace) -> int:
    from softplc.plant import Plant

    plant = Plant.from_file(args.plant)
    links = ", ".join(f"{n} ({lk.master} + {', '.join(lk.peers)})"
                      for n, lk in plant.links.items()) or "none"
    print(f"{args.plant}: OK - {len(plant.controllers)} controllers, links: {links}, "
          f"{len(plant.wires)} wires, {len(plant.devices)} shared devices")
    plant.close()
    return 0


def _status(plant: Plant, show: list[str]) -> dict[str, Any]:
    st = plant.status()
    st["values"] = {k: plant[k] for k in show}
    for c in st["controllers"].values():
        c["state"] = str(c["state"])
    return st


def _print(plant: Plant, args: argparse.Namespace) -> None:
    st = _status(plant, args.show)
    if args.json:
        print(json.dumps(st), flush=True)
        return
    parts = []
    for name, c in st["controllers"].items():
        link = c["link"]
        health = "" if link is None else f" link 16#{link['status']:04X}/{link['error']}"
        parts.append(f"{name} {c['state']} {c['scans']} scans{health}")
    values = " ".join(f"{k}={v}" for k, v in st["values"].items())
    print(f"t={st['time']:.3f}s  " + "; ".join(parts) + (f"  {values}" if values else ""),
          flush=True)


def _run(args: argparse.Namespace) -> int:
    from softplc.plant import Plant

    plant = Plant.from_file(args.plant)
    page = None
    if args.web is not None:
        from softplc.plant.view import plant_view
        from softplc.web.plantpage import PlantPage

        page = PlantPage(args.web)
        page.publish(plant_view(plant))
        print(f"plant page: {page.start()}", flush=True)
    try:
        for key, value in args.set:
            plant[key] = value
        for key in args.show:
            plant[key]  # noqa: B018 (an unknown key fails now, not at the first status)
        _loop(plant, args, page)
    except KeyboardInterrupt:
        pass
    finally:
        if page is not None:
            page.stop()
        _print(plant, args)
        plant.close()
    return 0


def _loop(plant: Plant, args: argparse.Namespace, page: Any = None) -> None:
    end = None if args.duration is None else round(args.duration * 1e6)
    next_publish = time.monotonic()
    every = None if args.every is None else max(1, round(args.every * 1e6))
    next_print = every
    wall0 = time.monotonic()
    while end is None or plant.next_time() < end:
        plant.step()
        if every is not None and plant.now_us >= next_print:
            _print(plant, args)
            next_print += every
        if page is not None and time.monotonic() >= next_publish:
            from softplc.plant.view import plant_view

            page.publish(plant_view(plant))
            next_publish = time.monotonic() + PUBLISH_S
        if not math.isinf(args.speed):
            ahead = plant.now_us / 1e6 / args.speed - (time.monotonic() - wall0)
            while ahead > 0:  # pacing: plant time no faster than speed x real time
                time.sleep(min(ahead, PACE_SLICE_S))
                ahead = plant.now_us / 1e6 / args.speed - (time.monotonic() - wall0)
    if end is not None:
        plant.now_us = max(plant.now_us, end)
