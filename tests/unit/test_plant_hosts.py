"""`plant up`'s command lines and addresses (softplc.plant.hosts), without namespaces."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.errors import PlantStateError
from softplc.plant import hosts
from softplc.plant.model import load_plant
from softplc.plant.process import PhysicalProcess, wired_io

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "ladder_programs" / "plant" / "plant.toml"


def test_each_controller_gets_its_address_and_its_link_options():
    spec = load_plant(EXAMPLE)
    addr = hosts.addresses(spec)
    cmds = hosts._commands(spec, addr)
    assert set(cmds) == set(spec.data.controllers)
    master = cmds["master"]
    for peer in ("filler", "capper"):
        a = spec.data.controllers[peer].address
        assert f"{a}={addr[peer]}:{hosts.LINK_PORT}" in master
        assert cmds[peer][cmds[peer].index("--link-listen") + 1] == \
            f"{addr[peer]}:{hosts.LINK_PORT}"
        assert "--link-remote" not in cmds[peer]
    assert len(set(addr.values())) == len(addr)
    assert all(c[c.index("--port") + 1] == str(hosts.MODBUS_PORT) for c in cmds.values())


def test_a_linked_controller_without_its_remote_link_section_is_refused(tmp_path):
    (tmp_path / "m.il").write_text("LD 1\n[ %QNW1.0 := 1 ]\n")
    (tmp_path / "p.il").write_text("LD 1\n[ %QNW0.0 := 1 ]\n")
    (tmp_path / "plant.toml").write_text(
        '[controllers.m]\nprogram = "m.il"\naddress = 0\n'
        '[controllers.p]\nprogram = "p.il"\naddress = 1\n'
        '[links.l]\nmaster = "m"\npeers = ["p"]\n')
    spec = load_plant(tmp_path / "plant.toml")
    with pytest.raises(PlantStateError, match=r"\[remote_link\] section"):
        hosts._commands(spec, hosts.addresses(spec))


def test_down_without_a_record_says_so(tmp_path):
    with pytest.raises(PlantStateError, match="no plant is up"):
        hosts.down(tmp_path / "sp000000.json")


def test_each_wired_controller_gets_its_wire_options_and_the_plant_host_as_peer():
    spec = load_plant(EXAMPLE)
    cmds = hosts._commands(spec, hosts.addresses(spec), "10.0.35.252", web=True)
    io = wired_io(spec)
    assert io["master"] == (["%I0.1", "%I0.2", "%I0.3"], ["%Q0.0", "%Q0.2"])
    assert io["filler"] == (["%I0.0", "%I0.5"], ["%Q0.1"])
    for name, (ins, outs) in io.items():
        cmd = cmds[name]
        assert cmd[cmd.index("--wire-peer") + 1] == "10.0.35.252"
        assert cmd[cmd.index("--wire-in") + 1] == ",".join(ins)
        assert cmd[cmd.index("--wire-out") + 1] == ",".join(outs)
        assert cmd[cmd.index("--web-host") + 1] == hosts.addresses(spec)[name]
        assert not any("token" in part.lower() for part in cmd)  # not in `ps`


class FakeClient:
    """A controller's end of the wires: its outputs as set, the inputs it got."""

    def __init__(self, outputs: dict[str, bool]):
        self.outputs = outputs
        self.got: dict[str, bool] = {}
        self.connected = True

    def exchange(self, inputs: list[bool]) -> tuple[bool, ...] | None:
        self.got = inputs
        return tuple(self.outputs.values()) if self.connected else None

    def close(self) -> None:
        pass


def test_the_plant_host_runs_the_belt_from_the_controllers_wired_outputs():
    spec = load_plant(EXAMPLE)
    proc = PhysicalProcess(spec, hosts.addresses(spec))
    master = FakeClient({"%Q0.0": True, "%Q0.2": True})  # belt motor, line enable
    proc.clients = {"master": master, "filler": FakeClient({"%Q0.1": True}),
                    "capper": FakeClient({"%Q0.1": False})}
    t = 0.0
    for _ in range(round(5.0 / proc.tick_s)):  # 5 s: the first box reaches the filler
        proc.step(t)
        t += proc.tick_s
    belt = proc.devices["belt"]
    assert belt.inputs["run"] and belt.inputs["hold_fill"]
    assert proc.inputs["filler"] == {"%I0.0": True, "%I0.5": True}  # the fill eye, enable
    assert proc.inputs["master"]["%I0.1"] is True  # the same eye, the master's input
    assert proc.clients["filler"].got == [True, True]
    # the master loses power: its outputs read 0, the belt stops, the enable drops
    master.connected = False
    proc.step(t)
    proc.step(t + proc.tick_s)
    assert belt.inputs["run"] is False
    assert proc.inputs["capper"]["%I0.5"] is False


def test_the_record_is_never_read_half_written(tmp_path, monkeypatch):
    """Issue 33: `plant up` rewrites its record while the page's process reads it (the
    page failed to start on an empty file under load). A reader beside a writer that keeps
    rewriting it, with a pause after each write's open (where a truncating write leaves
    the file empty), always finds a whole record."""
    import json
    import os
    import threading

    path = tmp_path / "sp.json"
    record: dict = {"controllers": {}}
    hosts.write_record(path, record)
    real_fdopen, opened = os.fdopen, threading.Event()

    def slow_fdopen(fd, *a, **k):  # the injected delay: the file open, not yet written
        opened.set()
        threading.Event().wait(0.005)
        return real_fdopen(fd, *a, **k)

    writes, reads, bad = 40, [], []
    done = threading.Event()

    def read() -> None:
        while not done.is_set():
            try:
                reads.append(len(json.loads(path.read_text())["controllers"]))
            except ValueError as e:
                bad.append(e)

    reader = threading.Thread(target=read)
    monkeypatch.setattr(os, "fdopen", slow_fdopen)
    reader.start()
    try:
        for i in range(writes):
            record["controllers"][f"c{i}"] = {"pid": i}
            hosts.write_record(path, record)
    finally:
        done.set()
        reader.join()
        monkeypatch.undo()
    assert opened.is_set() and reads and not bad, bad[:1]
    assert json.loads(path.read_text())["controllers"] == record["controllers"]
    assert path.stat().st_mode & 0o777 == 0o600 and not list(tmp_path.glob(".*.tmp"))
