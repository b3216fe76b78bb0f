"""What the plant page shows (softplc.web.plantpage): a JSON-ready view of a plant between
two steps. The scan time is the host's CPU time for the last scan (what %SW30 shows in
ms, here in us: a plant's scans are well under 1 ms)."""

from __future__ import annotations

from typing import Any

from softplc.runtime.remotelink import MASTER, LinkMaster
from softplc.twido.address import LINK_WORDS


def _words(mem: Any, family: str, station: int) -> list[int]:
    w = getattr(mem, family).w
    return [w[station * LINK_WORDS + j] for j in range(LINK_WORDS)]


def plant_view(plant: Any) -> dict[str, Any]:
    """What the page shows, from a plant between two steps (softplc.plant.Plant)."""
    st = plant.status()
    out: dict[str, Any] = {"name": plant.name, "time": st["time"], "controllers": [],
                           "devices": st["devices"]}
    for name, c in st["controllers"].items():
        ctl = plant.controllers[name]
        mem, link = ctl.plc.mem, ctl.plc.machine.link
        words: dict[str, Any] = {}
        if isinstance(link, LinkMaster):
            for a in link.remotes:
                words[str(a)] = {"sent": _words(mem, "qnw", a), "received": _words(mem, "inw", a),
                                 "present": link.present(a)}
        elif link is not None:
            words[str(MASTER)] = {"sent": _words(mem, "qnw", MASTER),
                                  "received": _words(mem, "inw", MASTER)}
        out["controllers"].append({
            "name": name, "state": str(c["state"]), "scans": c["scans"],
            "scan_us": round(ctl.plc.stats.last * 1e6), "link": c["link"], "address":
                None if link is None else link.address, "words": words})
    return out
