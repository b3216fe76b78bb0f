"""Faults as a plant sees them (issue 35, 5): a controller killed and restarted, stopped
and started, a wire broken and mended, a link slowed. `Plant.faults` is one."""

from __future__ import annotations

from typing import Any

from softplc.errors import PlantStateError
from softplc.runtime.remotelink import LinkRemote


class Faults:
    """The fault switches of one plant."""

    def __init__(self, plant: Any):
        # the Plant (softplc.plant.plant, which imports this module: not named here)
        self.plant = plant

    def kill(self, name: str) -> None:
        """Controller `name` loses power: no more scans, its outputs drop to 0, it leaves
        the link (its master sees it absent after remotelink.MISSES cycles)."""
        c = self.plant._controller(name)
        c.alive = False
        c.plc.mem.q_field[:] = [False] * len(c.plc.mem.q_field)
        station = c.plc.machine.link
        if isinstance(station, LinkRemote) and c.link is not None:
            self.plant.links[c.link].transport.detach(station.address)

    def restart(self, name: str) -> None:
        """Power controller `name` up again: a cold start of its program on a new memory
        image, from the plant's time on; it rejoins its link (the rest keep running)."""
        c = self.plant._controller(name)
        if c.alive:
            raise PlantStateError(f"{name} is running: kill it first")
        c.plc.close()
        c.plc = self.plant._build(name, self.plant.now_us)
        c.alive = True
        if c.link is not None:
            self.plant._join(self.plant.links[c.link], name)
        self.plant._wire()
        self.plant.serve_exchanges()

    def stop(self, name: str) -> None:
        """Controller `name` to STOP (it still answers on the link)."""
        self.plant._controller(name).plc.stop()

    def start(self, name: str) -> None:
        self.plant._controller(name).plc.start()

    def _wire_named(self, name: str) -> Any:
        for w in self.plant.wires:
            if w.name == name:
                return w
        raise PlantStateError(f"no wire {name!r} (wires: "
                              f"{', '.join(w.name for w in self.plant.wires) or 'none'})")

    def break_wire(self, name: str) -> None:
        """Wire `name` broken: its inputs read 0 (an open circuit) until `mend_wire`."""
        w = self._wire_named(name)
        w.broken = True
        for t in w.targets:
            cell, key = self.plant._cell(t, output=False)
            cell[key] = False
        self.plant._wire()

    def mend_wire(self, name: str) -> None:
        self._wire_named(name).broken = False
        self.plant._wire()

    def slow_link(self, peer: str, cycles: int) -> None:
        """The line to peer `peer` delays its words by `cycles` link cycles each way."""
        c = self.plant._controller(peer)
        station = c.plc.machine.link
        if not isinstance(station, LinkRemote) or c.link is None:
            raise PlantStateError(f"{peer} is not a peer on a link")
        self.plant.links[c.link].transport.delay(station.address, cycles)
