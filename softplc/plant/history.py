"""A plant's own state between instants, for the debugger's `back` (issue 35): its time,
the shared devices, each Remote Link's cycle and stations and the words in flight. The
controllers' engines are snapshotted by `Engine.snapshot()` (through the debugger's
steppers, which also keep their queued writes). Structure (a killed controller, a broken
wire: `plant.faults`) is not part of it."""

from __future__ import annotations

from typing import Any

from softplc.plant.plant import Plant


def checkpoint(plant: Plant) -> dict[str, Any]:
    """The plant's state at an instant's boundary, for `rewind`."""
    links = {}
    for name, lk in plant.links.items():
        stations = {m: st.state() for m in [lk.master, *lk.peers]
                    if (st := plant.controllers[m].plc.machine.link) is not None}
        links[name] = (lk.next_us, lk.cycles, lk.transport.state(), stations)
    return {"now_us": plant.now_us, "next_dev": plant._next_dev,
            "devices": {n: d.state() for n, d in plant.devices.items()}, "links": links}


def rewind(plant: Plant, cp: dict[str, Any]) -> None:
    """Back to a `checkpoint()` of this plant."""
    plant.now_us, plant._next_dev = cp["now_us"], cp["next_dev"]
    for n, st in cp["devices"].items():
        plant.devices[n].set_state(st)
    for n, (next_us, cycles, transport, stations) in cp["links"].items():
        lk = plant.links[n]
        lk.next_us, lk.cycles = next_us, cycles
        lk.transport.set_state(transport)
        for m, st in stations.items():
            station = plant.controllers[m].plc.machine.link
            if station is not None:
                station.set_state(st)
