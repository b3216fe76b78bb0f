"""The plant page of `plant up` (softplc.commands.plantweb): its view built from each
controller's monitor (a fake API client here), the same shape as `plant run`'s."""

from __future__ import annotations

from pathlib import Path

from softplc.commands.io import IoError
from softplc.commands.plantweb import OFF, remote_view
from softplc.plant.model import load_plant

EXAMPLE = Path(__file__).resolve().parents[2] / "ladder_programs" / "plant" / "plant.toml"


class FakeMonitor:
    """A controller's web API: its status and objects (None: it does not answer)."""

    def __init__(self, values: dict[str, int] | None, scans: int = 7):
        self.values, self.scans = values, scans
        self.asked: list[str] = []

    def status(self) -> dict:
        if self.values is None:
            raise IoError("no softplc web API")
        return {"state": "RUN", "scans": self.scans, "scan_last_ms": 0.025}

    def get(self, *objects: str) -> dict[str, int]:
        assert self.values is not None
        self.asked += objects
        return {o: self.values.get(o, 0) for o in objects}


def _record() -> dict:
    hosts = {"master": "10.0.35.1", "filler": "10.0.35.2", "capper": "10.0.35.3"}
    return {"read_token": "R", "controllers": {
        n: {"host": h, "web_port": 8020} for n, h in hosts.items()}}


def test_the_view_has_each_controllers_state_link_words_and_monitor():
    spec = load_plant(EXAMPLE)
    master = FakeMonitor({"%SW111": 0b01, "%SW112": 1, "%QNW1.1": 15, "%INW2.0": 4})
    clients = {"master": master, "filler": FakeMonitor({"%INW0.1": 15, "%SW111": 1}),
               "capper": FakeMonitor(None)}
    view = remote_view(spec, _record(), clients, since=0.0)
    assert view["name"] == "bottling line"
    rows = {r["name"]: r for r in view["controllers"]}
    assert list(rows) == ["master", "filler", "capper"]
    m = rows["master"]
    assert (m["state"], m["scans"], m["scan_us"], m["address"]) == ("RUN", 7, 25, 0)
    assert m["link"] == {"status": 1, "error": 1, "config": 0}
    assert m["words"]["1"] == {"sent": [0, 15, 0, 0], "received": [0, 0, 0, 0],
                               "present": True}
    assert m["words"]["2"]["present"] is False and m["words"]["2"]["received"][0] == 4
    assert "%QNW2.3" in master.asked and "%INW1.0" in master.asked
    f = rows["filler"]
    assert f["address"] == 1 and f["words"] == {"0": {"sent": [0, 0, 0, 0],
                                                      "received": [0, 15, 0, 0]}}
    assert f["monitor"] == "http://10.0.35.2:8020/?token=R"  # the read-only token
    assert rows["capper"]["state"] == OFF and rows["capper"]["link"] is None
