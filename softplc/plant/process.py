"""The shared physical process as a host of its own (`softplc plant process`, started by
`plant up`; docs/decisions/wires-over-tcp.md): the plant's shared devices and wires on
the real clock, each controller's wired inputs and outputs exchanged over TCP with its
`softplc run --wire-listen` daemon (softplc.runtime.wiretcp).

Every device tick, in `Plant.step`'s order: each controller's wired outputs are read (the
answer to the tick's exchange), the wires into the devices copied, the devices moved on by
one tick, the other wires copied, and each controller gets its wired inputs. A wire from
one controller to another passes here too: one tick late, as through a relay cabinet. A
controller that does not answer drives nothing: its outputs read 0 (a controller without
power), and it is tried again every `wiretcp.RETRY_S`.
"""

from __future__ import annotations

import time
from typing import Any

from softplc.plant.model import Endpoint, PlantSpec
from softplc.plant.physics import SHARED_DEVICES, SharedDevice
from softplc.runtime.wiretcp import WireClient

WIRE_PORT = 5102  # where a controller answers the plant host's wires (a softplc choice)
DEFAULT_TICK_S = 0.010  # the devices' step without a `tick` in the plant file


def wired_io(spec: PlantSpec) -> dict[str, tuple[list[str], list[str]]]:
    """Each controller with wires: (its wired inputs, its wired outputs), sorted, as
    `--wire-in` / `--wire-out` give them and the plant host sends and reads them."""
    ins: dict[str, set[str]] = {}
    outs: dict[str, set[str]] = {}
    for _, src, targets in spec.wires:
        if not src.device:
            outs.setdefault(src.owner, set()).add(src.what)
        for t in targets:
            if not t.device:
                ins.setdefault(t.owner, set()).add(t.what)
    return {n: (sorted(ins.get(n, ())), sorted(outs.get(n, ())))
            for n in spec.data.controllers if n in ins or n in outs}


class PhysicalProcess:
    """The devices and wires of a plant, its controllers reached over TCP."""

    def __init__(self, spec: PlantSpec, hosts: dict[str, str], port: int = WIRE_PORT):
        self.spec = spec
        self.devices: dict[str, SharedDevice] = {
            name: SHARED_DEVICES[spec.data.devices[name].type](name, opts)
            for name, opts in spec.device_options.items()}
        self.io = wired_io(spec)
        self.inputs = {n: dict.fromkeys(i, False) for n, (i, _) in self.io.items()}
        self.outputs = {n: dict.fromkeys(o, False) for n, (_, o) in self.io.items()}
        self.clients = {n: WireClient(n, (hosts[n], port), i, o)
                        for n, (i, o) in self.io.items()}
        self.tick_s = spec.data.tick or DEFAULT_TICK_S
        self.ticks = 0
        into, other = [], []
        for _, src, targets in spec.wires:
            cell = self._cell(src, output=True)
            for t in targets:
                (into if t.device else other).append((*cell, *self._cell(t, output=False)))
        self._into_devices, self._other_wires = into, other

    def _cell(self, e: Endpoint, output: bool) -> tuple[dict[str, bool], str]:
        if e.device:
            dev = self.devices[e.owner]
            return (dev.outputs if output else dev.inputs), e.what
        return (self.outputs if output else self.inputs)[e.owner], e.what

    def step(self, t: float) -> None:
        """One device tick at time `t` (s): the wires, the devices, the exchanges."""
        for src, k, dst, j in self._into_devices:
            dst[j] = src[k]
        for dev in self.devices.values():
            dev.update(t, self.tick_s)
        for src, k, dst, j in self._other_wires:
            dst[j] = src[k]
        for name, client in self.clients.items():
            got = client.exchange(list(self.inputs[name].values()))
            outs = self.outputs[name]
            for k, v in zip(outs, got or (False,) * len(outs), strict=True):
                outs[k] = v
        self.ticks += 1

    def run(self, stop: Any) -> None:
        """Tick on the real clock until `stop()` is true; a late tick is not made up."""
        t0 = due = time.monotonic()
        while not stop():
            self.step(due - t0)
            due += self.tick_s
            now = time.monotonic()
            if due < now:  # an overrun (a controller slow to answer): start again from now
                due = now
            time.sleep(due - now)

    def status(self) -> dict[str, Any]:
        return {"ticks": self.ticks,
                "controllers": {n: {"connected": c.connected, "exchanges": c.exchanges,
                                    "failures": c.failures} for n, c in self.clients.items()},
                "devices": {n: d.status() for n, d in self.devices.items()}}

    def close(self) -> None:
        for c in self.clients.values():
            c.close()
