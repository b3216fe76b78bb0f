"""`Plant`: every controller, link, wire and shared device of a plant file in one process,
on one virtual clock (issue 35).

    plant = Plant.from_file("ladder_programs/plant/plant.toml")
    plant.run(10.0)                      # ten seconds of plant time
    plant["filler:%MW0"], plant["belt:at_fill"]
    plant.faults.kill("filler"); plant.scan(5); plant.faults.restart("filler")

Time is integer microseconds, shared by all: each controller keeps its own scan period
(its configuration's), the Remote Link masters their link cycle, the shared devices the
plant's `tick`. `step()` moves the plant to the next instant anything is due and runs, in
this fixed order, what is due then:

  1. the wires into the shared devices (a controller's output -> a device's input);
  2. the shared devices (`update(t, dt)`), every tick;
  3. the other wires (a device's signal or a controller's output -> a controller's input);
  4. each Remote Link whose cycle is due: the remotes' `tick`, then the master's `cycle`
     (the exchange runs between scans, on its own cycle, never inside one);
  5. the scans due, controllers in the file's order.

Nothing reads the wall clock, so a plant run is the same on every run and every machine.
With every controller on one scan period, one `step()` (or `scan()`) is one scan of each.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.errors import PlantStateError
from softplc.modbus.image import ModbusImage
from softplc.modbus.protocol import process_pdu
from softplc.plant.faults import Faults
from softplc.plant.model import Endpoint, PlantSpec, load_plant
from softplc.plant.physics import SHARED_DEVICES, SharedDevice
from softplc.plc import PLC
from softplc.runtime.clock import VirtualClock
from softplc.runtime.engine import SW_LAST, SW_MAX, SW_MIN
from softplc.runtime.exch import ERR_TIMEOUT, ExchError
from softplc.runtime.remotelink import InMemoryTransport, LinkMaster, LinkRemote
from softplc.twido.address import parse_address

NEVER = 1 << 62  # a due time that never comes (no link, no device)
MEASURED_WORDS = (SW_LAST, SW_MAX, SW_MIN)  # scan times: wall-clock measurements


@dataclass
class Controller:
    """One soft Twido of the plant and its place on the link."""

    name: str
    program: Path | None  # None: a remote I/O controller
    config: Any  # assembly.Loaded
    plc: PLC
    alive: bool = True
    link: str | None = None  # the Remote Link it is on


@dataclass
class Wire:
    name: str
    source: Endpoint
    targets: list[Endpoint]
    broken: bool = False


@dataclass
class Link:
    """A Remote Link run in memory: the master's station polls over the transport."""

    name: str
    master: str
    peers: list[str]
    transport: InMemoryTransport = field(default_factory=InMemoryTransport)
    cycle_us: int = 0
    next_us: int = 0
    cycles: int = 0  # link cycles run


class Plant:
    """Controllers, links, wires and shared devices on one virtual clock."""

    def __init__(self, spec: PlantSpec):
        self.spec = spec
        self.name = spec.data.name or spec.file.stem
        self.now_us = 0
        self.controllers: dict[str, Controller] = {}
        for name in spec.data.controllers:
            self.controllers[name] = Controller(name, spec.programs.get(name),
                                                spec.configs[name], self._build(name, 0))
        self.devices: dict[str, SharedDevice] = {
            name: SHARED_DEVICES[spec.data.devices[name].type](name, opts)
            for name, opts in spec.device_options.items()}
        self.links: dict[str, Link] = {}
        for lname, entry in spec.data.links.items():
            if entry.type != "remote_link":
                continue
            assert entry.master is not None
            link = self.links[lname] = Link(lname, entry.master, list(entry.peers))
            for member in [entry.master, *entry.peers]:
                self.controllers[member].link = lname
            master = self._station(entry.master)
            assert isinstance(master, LinkMaster)
            link.cycle_us = master.cycle_us
            self._join(link, entry.master)
            for peer in entry.peers:
                self._join(link, peer)
        periods = [c.plc.engine.period_us for c in self.controllers.values()]
        self.tick_us = round(spec.data.tick * 1e6) if spec.data.tick else min(periods)
        self._next_dev = 0 if self.devices else NEVER
        self.wires = [Wire(n, s, t) for n, s, t in spec.wires]
        self._wire()
        self._images: dict[str, ModbusImage] = {}
        self.serve_exchanges()
        self.faults = Faults(self)

    @classmethod
    def from_file(cls, path: str | Path) -> Plant:
        """The plant of a plant file (PlantError: every problem with its line)."""
        return cls(load_plant(path))

    # -- building --------------------------------------------------------------------------
    def _build(self, name: str, start_us: int) -> PLC:
        program = self.spec.programs.get(name)
        if program is None:  # a remote I/O controller: no program, its I/O the master's
            return PLC.from_source("", self.spec.configs[name], file=f"<remote I/O {name}>",
                                   clock=VirtualClock(start_us))
        return PLC.from_file(program, self.spec.configs[name], clock=VirtualClock(start_us))

    def _station(self, name: str) -> LinkMaster | LinkRemote | None:
        return self.controllers[name].plc.machine.link

    def _join(self, link: Link, name: str) -> None:
        """Put controller `name`'s (new) station on `link`."""
        station = self._station(name)
        if isinstance(station, LinkMaster):
            station.transport = link.transport
        elif isinstance(station, LinkRemote):
            link.transport.attach(station)

    def serve_exchanges(self) -> None:
        """The EXCH links: each client's remote devices served in memory by the named
        controllers' Modbus maps (a killed one does not answer: the client's EXCH times
        out). Called again when a controller restarts (a new memory image)."""
        for entry in self.spec.data.links.values():
            if entry.type != "exch":
                continue
            port = self.controllers[entry.client].plc.machine.exch
            assert port is not None  # the plant gave the client its [exch] remotes
            for index, name in entry.remotes.items():
                port.local[index] = self._server(name)

    def _server(self, name: str) -> Callable[[bytes], bytes]:
        c = self.controllers[name]
        img = self._images.get(name)
        if img is None or img.mem is not c.plc.mem:
            img = self._images[name] = ModbusImage(c.plc.mem)
            c.plc.before_scan.append(img.apply_writes)  # as the daemon's server does
            c.plc.after_scan.append(img.take_snapshot)

        def serve(pdu: bytes) -> bytes:
            if not self.controllers[name].alive:
                raise ExchError(ERR_TIMEOUT, f"{name} does not answer")
            return process_pdu(img, pdu)
        return serve

    def _wire(self) -> None:
        """The wires as (source container, key, target container, key) copies, those into
        devices apart; a broken wire copies nothing (its targets were set to 0)."""
        into, other = [], []
        for w in self.wires:
            if w.broken:
                continue
            src = self._cell(w.source, output=True)
            for t in w.targets:
                (into if t.device else other).append((*src, *self._cell(t, output=False)))
        self._into_devices, self._other_wires = into, other

    def _cell(self, e: Endpoint, output: bool) -> tuple[Any, Any]:
        if e.device:
            dev = self.devices[e.owner]
            return (dev.outputs if output else dev.inputs), e.what
        mem = self.controllers[e.owner].plc.mem
        ref = parse_address(e.what, mem.profile)
        mem.use_io(ref)
        return (mem.q_field if output else mem.i_field), ref.index

    # -- running ---------------------------------------------------------------------------
    def next_time(self) -> int:
        """When the next thing is due (us of plant time)."""
        t = self._next_dev
        for c in self.controllers.values():
            if c.alive and c.plc.clock.now_us < t:
                t = c.plc.clock.now_us
        for link in self.links.values():
            if link.next_us < t:
                t = link.next_us
        return t

    def step(self) -> None:
        """Move to the next instant anything is due and run it (the module's order)."""
        for c in self.begin_step():
            c.plc.engine.scan()

    def begin_step(self) -> list[Controller]:
        """Move to the next instant anything is due and run all of it but the scans
        (steps 1-4); the controllers whose scan is due, in the file's order (the debugger
        runs those scans itself, to stop inside one)."""
        t = self.next_time()
        if t >= NEVER:
            raise PlantStateError("nothing left to run: every controller is off")
        self.now_us = t
        for src, k, dst, j in self._into_devices:
            dst[j] = src[k]
        if t >= self._next_dev:
            dt = self.tick_us / 1e6
            for dev in self.devices.values():
                dev.update(t / 1e6, dt)
            self._next_dev += self.tick_us
        for src, k, dst, j in self._other_wires:
            dst[j] = src[k]
        for link in self.links.values():
            if t >= link.next_us:
                self._link_cycle(link)
                link.next_us += link.cycle_us
        return [c for c in self.controllers.values() if c.alive and c.plc.clock.now_us <= t]

    def _link_cycle(self, link: Link) -> None:
        link.cycles += 1
        for remote in link.transport.remotes():
            remote.tick()
        if self.controllers[link.master].alive:
            master = self._station(link.master)
            assert isinstance(master, LinkMaster)
            master.cycle()

    def scan(self, n: int = 1) -> None:
        """n steps (with one scan period for all: n scans of every controller)."""
        for _ in range(n):
            self.step()

    def run(self, seconds: float) -> None:
        """Run everything due in the next `seconds` of plant time."""
        end = self.now_us + round(seconds * 1e6)
        while self.next_time() < end:
            self.step()
        self.now_us = max(self.now_us, end)

    def run_until(self, condition: Callable[[Plant], Any], timeout: float = 10.0) -> bool:
        """Step until condition(plant) is true or `timeout` seconds of plant time pass."""
        end = self.now_us + round(timeout * 1e6)
        while not condition(self):
            if self.next_time() >= end:
                return bool(condition(self))
            self.step()
        return True

    @property
    def time(self) -> float:
        """Plant time in seconds."""
        return self.now_us / 1e6

    # -- access ----------------------------------------------------------------------------
    def _split(self, key: str) -> tuple[str, str]:
        owner, sep, what = key.partition(":")
        if not sep or (owner not in self.controllers and owner not in self.devices):
            raise PlantStateError(f"{key!r}: write CONTROLLER:%ADDRESS or DEVICE:SIGNAL "
                                  f"(controllers {', '.join(self.controllers)}; devices "
                                  f"{', '.join(self.devices) or 'none'})")
        return owner, what

    def __getitem__(self, key: str) -> Any:
        owner, what = self._split(key)
        if owner in self.controllers:
            return self.controllers[owner].plc[what]
        dev = self.devices[owner]
        if what in dev.outputs:
            return dev.outputs[what]
        if what in dev.inputs:
            return dev.inputs[what]
        raise PlantStateError(f"{key!r}: {owner} has signals "
                              f"{', '.join([*dev.inputs, *dev.outputs])}")

    def __setitem__(self, key: str, value: Any) -> None:
        owner, what = self._split(key)
        if owner not in self.controllers:
            raise PlantStateError(f"{key!r}: a device's signals are set by wires")
        self.controllers[owner].plc[what] = value

    def plc(self, name: str) -> PLC:
        return self._controller(name).plc

    def _controller(self, name: str) -> Controller:
        if name not in self.controllers:
            raise PlantStateError(f"no controller {name!r} (controllers: "
                                  f"{', '.join(self.controllers)})")
        return self.controllers[name]

    # -- views -----------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """Each controller's state, scans and link status; each device's status."""
        out: dict[str, Any] = {"time": self.time, "controllers": {}, "devices": {}}
        for name, c in self.controllers.items():
            st = c.plc.machine.link.status() if c.plc.machine.link is not None else None
            out["controllers"][name] = {
                "state": c.plc.state if c.alive else "OFF", "scans": c.plc.scan_count,
                "link": st}
        for name, dev in self.devices.items():
            out["devices"][name] = dev.status()
        return out

    def snapshot(self) -> dict[str, Any]:
        """The whole plant's state (memory images, devices): equal for equal runs. The
        scan times %SW30-%SW32 measure the host, not the plant: left out (zero)."""
        def image(c: Controller) -> dict[str, Any]:
            snap = c.plc.mem.snapshot()
            sw = bytearray(snap["sw"])
            for k in MEASURED_WORDS:
                sw[2 * k:2 * k + 2] = b"\0\0"
            snap["sw"] = bytes(sw)
            return snap

        return {"time": self.now_us,
                "controllers": {n: (c.alive, image(c)) for n, c in self.controllers.items()},
                "devices": {n: d.state() for n, d in self.devices.items()}}

    def close(self) -> None:
        for c in self.controllers.values():
            c.plc.close()
