"""`softplc plant`: a plant of soft Twidos (issue 35).

    softplc plant check plant.toml                 # load and build; every error, with its line
    softplc plant run plant.toml [--speed max] [--for 60s] [--set master:%I0.0=1]
                                 [--print master:%MW0] [--every 10s] [--json]

`run` runs every controller, link, wire and shared device of the plant file in this
process on one virtual clock (softplc.plant): the same result on every run. `--speed N`
paces plant time at N times real time (default 1), `max` as fast as it goes.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from typing import TYPE_CHECKING, Any

from softplc.commands.run import _speed

if TYPE_CHECKING:  # imported when the command runs: `softplc --help` stays light
    from softplc.plant import Plant

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
    r.set_defaults(func=_run)


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
    try:
        for key, value in args.set:
            plant[key] = value
        for key in args.show:
            plant[key]  # noqa: B018 (an unknown key fails now, not at the first status)
        _loop(plant, args)
    except KeyboardInterrupt:
        pass
    finally:
        _print(plant, args)
        plant.close()
    return 0


def _loop(plant: Plant, args: argparse.Namespace) -> None:
    end = None if args.duration is None else round(args.duration * 1e6)
    every = None if args.every is None else max(1, round(args.every * 1e6))
    next_print = every
    wall0 = time.monotonic()
    while end is None or plant.next_time() < end:
        plant.step()
        if every is not None and plant.now_us >= next_print:
            _print(plant, args)
            next_print += every
        if not math.isinf(args.speed):
            ahead = plant.now_us / 1e6 / args.speed - (time.monotonic() - wall0)
            while ahead > 0:  # pacing: plant time no faster than speed x real time
                time.sleep(min(ahead, PACE_SLICE_S))
                ahead = plant.now_us / 1e6 / args.speed - (time.monotonic() - wall0)
    if end is not None:
        plant.now_us = max(plant.now_us, end)
