"""The plant page of `softplc plant up` (issue 35, 6): the page of `plant run`
(softplc.web.plantpage) fed from the daemons' web monitors instead of one process' plant.

`plant up` starts `softplc plant page PLANT` in this machine's own namespace: every
`POLL_S` it asks each controller's monitor (on its own address, reached through the veth
`plant up` made into the plant network) for its status and its link words, and publishes
the same view as `plant_view` (softplc.plant.view), with a link to each controller's own
monitor. The links carry the read-only token: the page is read-only, and so is the monitor
a click on it opens; the full token stays in `plant up`'s record (owner only).
"""

from __future__ import annotations

import argparse
import json
import signal
import time
from typing import Any

from softplc.commands.io import Client, IoError
from softplc.errors import PlantStateError
from softplc.twido.address import LINK_WORDS

POLL_S = 0.5  # the page refreshes twice a second (softplc.web.plantpage)
ASK_S = 1.0  # the longest one monitor may take to answer (a killed one: refused at once)
OFF = "OFF"  # a controller whose monitor does not answer: killed or not started


def _link_words(spec: Any) -> dict[str, dict[int, str]]:
    """Each linked controller's stations whose words it shows: {station: role} (the
    master: its peers by address; a peer: the master, station 0)."""
    out: dict[str, dict[int, str]] = {}
    for link in spec.data.links.values():
        if link.type != "remote_link":
            continue
        out[link.master] = {spec.data.controllers[p].address: "peer" for p in link.peers}
        for p in link.peers:
            out[p] = {0: "master"}
    return out


def _objects(stations: dict[int, str]) -> list[str]:
    names = ["%SW111", "%SW112", "%SW113"] if stations else []
    for a in stations:
        names += [f"%{fam}{a}.{j}" for fam in ("QNW", "INW") for j in range(LINK_WORDS)]
    return names


def controller_view(name: str, client: Client, stations: dict[int, str],
                    monitor: str) -> dict[str, Any]:
    """One row of the page, from controller `name`'s monitor (state OFF: no answer)."""
    row: dict[str, Any] = {"name": name, "state": OFF, "scans": 0, "scan_us": 0,
                           "link": None, "address": None, "words": {}, "monitor": monitor}
    try:
        st = client.status()
        values = client.get(*_objects(stations)) if stations else {}
    except IoError:
        return row
    row.update(state=str(st["state"]), scans=st["scans"],
               scan_us=round(st["scan_last_ms"] * 1000))
    if not stations:
        return row
    status = int(values["%SW111"])
    row["link"] = {"status": status, "error": int(values["%SW112"]),
                   "config": int(values["%SW113"])}
    master = 0 not in stations
    for a in stations:
        words: dict[str, Any] = {
            "sent": [values[f"%QNW{a}.{j}"] for j in range(LINK_WORDS)],
            "received": [values[f"%INW{a}.{j}"] for j in range(LINK_WORDS)]}
        if master:
            words["present"] = bool(status >> (a - 1) & 1)
        row["words"][str(a)] = words
    return row


def remote_view(spec: Any, record: dict[str, Any], clients: dict[str, Client],
                since: float) -> dict[str, Any]:
    """The page's view of a plant that is up (`plant up`'s record)."""
    stations = _link_words(spec)
    rows = []
    for name, c in record["controllers"].items():
        monitor = f"http://{c['host']}:{c['web_port']}/?token={record['read_token']}"
        row = controller_view(name, clients[name], stations.get(name, {}), monitor)
        if name in stations:  # its Remote Link address
            row["address"] = spec.data.controllers[name].address or 0
        rows.append(row)
    return {"name": spec.data.name or spec.file.stem, "time": time.monotonic() - since,
            "controllers": rows, "devices": {}}


def serve(args: argparse.Namespace) -> int:
    """`softplc plant page PLANT --record FILE --port PORT`: until SIGTERM."""
    from softplc.plant.model import load_plant
    from softplc.web.plantpage import PlantPage

    spec = load_plant(args.plant)
    record = json.loads(args.record.read_text())
    clients = {n: Client(c["host"], c["web_port"], record["read_token"], timeout=ASK_S)
               for n, c in record["controllers"].items()}
    stopping: list[int] = []
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    since = time.monotonic()
    page = PlantPage(args.port)
    page.publish(remote_view(spec, record, clients, since))
    try:
        url = page.start()
    except OSError as e:
        page.stop()
        raise PlantStateError(f"plant page: cannot listen on 127.0.0.1:{args.port}: "
                              f"{e.strerror or e}; choose another --web PORT (0: any free "
                              f"one) or --web off") from None
    print(f"plant page: {url}", flush=True)
    try:
        while not stopping:
            time.sleep(POLL_S)
            page.publish(remote_view(spec, record, clients, since))
    except KeyboardInterrupt:
        pass
    finally:
        page.stop()
    return 0
