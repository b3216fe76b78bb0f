"""`softplc plant up --netns` / `plant down` (issue 35, softplc.plant.hosts): each controller
a `softplc run` daemon in its own network namespace, the Remote Link over TCP between
them, a SCADA namespace that reaches them all; a crash of one leaves the others running;
`down` removes everything. Skipped where network namespaces cannot be made."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from waits import WAIT_S, until_equal
from zygote import popen

from softplc.plant import hosts

ROOT = Path(__file__).resolve().parents[2]
WHY = hosts.netns_works()
pytestmark = [pytest.mark.skipif(bool(WHY), reason=f"network namespaces: {WHY}"),
              pytest.mark.usefixtures("netns_serial")]
READ_S = 0.1  # between reads: each starts a process in the SCADA's namespace
COMMAND_S = 120  # bounds a failing `softplc` command only

PLANT = """
name = "two"
[controllers.master]
program = "m.il"
config = "m.toml"
address = 0
[controllers.peer]
program = "p.il"
config = "p.toml"
address = 1
[links.line]
master = "master"
peers = ["peer"]
"""
FILES = {
    "m.il": "LD 1\n[ %QNW1.0 := %MW10 ]\n[ %MW0 := %INW1.0 ]\n[ %MW1 := %SW111 ]\n",
    "p.il": "LD 1\n[ %QNW0.0 := %INW0.0 + 1 ]\n",
    "m.toml": 'scan_period = "10ms"\n[remote_link]\naddress = 0\nremotes = { 1 = "peer" }\n'
              'cycle = "20ms"\n',
    "p.toml": 'scan_period = "10ms"\n[remote_link]\naddress = 1\n',
    "plant.toml": PLANT,
}
READ = """
import sys, time
from softplc.modbus.rawclient import RawClient
c = RawClient(sys.argv[1], 502, timeout=3)
if len(sys.argv) > 2:
    c.write_registers(10, [int(sys.argv[2])])
print(*c.read_registers(0, 2))
"""


def _softplc(tmp: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """`python -m softplc ARGS`, forked from the test zygote (tests/zygote.py), which has
    imported what `plant up` preloads for its daemons (a second of CPU a start);
    tests/e2e/test_plant_up_browser.py starts the real `plant up` and `plant down`."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = popen(list(args), tmp, env)
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.append(proc.stderr.read()))  # type: ignore[union-attr]
    reader.start()
    out = proc.stdout.read()  # type: ignore[union-attr]
    reader.join(COMMAND_S)
    return subprocess.CompletedProcess(args, proc.wait(COMMAND_S), out, "".join(err))


def _from_scada(ns: str, host: str, *args: str) -> list[int]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run(["ip", "netns", "exec", ns, sys.executable, "-c", READ, host, *args],
                         capture_output=True, text=True, env=env, timeout=30)
    assert out.returncode == 0, out.stderr
    return [int(v) for v in out.stdout.split()]


def test_plant_up_runs_each_controller_in_its_namespace_and_down_removes_all(tmp_path):
    for name, text in FILES.items():
        (tmp_path / name).write_text(text)
    state = tmp_path / "state"
    t = hosts.tag(tmp_path / "plant.toml")
    up = _softplc(tmp_path, "plant", "up", "plant.toml", "--netns", "--state-dir", str(state),
                  "--web", "0")  # the page on any free port: 8030 may be another's
    try:
        assert up.returncode == 0, up.stderr
        scada = f"sp{t}-scada"
        made = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
        assert all(f"sp{t}-{n}" in made for n in ("scada", "master", "peer"))
        # the SCADA namespace reaches the master; the link runs between the namespaces
        _from_scada(scada, "10.35.0.1", "41")
        assert until_equal(lambda: _from_scada(scada, "10.35.0.1"), [42, 1],
                           WAIT_S, READ_S) == [42, 1]
        again = _softplc(tmp_path, "plant", "up", "plant.toml", "--netns", "--state-dir",
                         str(state))
        assert again.returncode != 0 and "already up" in again.stderr
        # the peer crashes: the master runs on and shows it absent on the link
        record = json.loads((state / f"sp{t}.json").read_text())
        os.killpg(record["controllers"]["peer"]["pid"], signal.SIGKILL)
        assert until_equal(lambda: _from_scada(scada, "10.35.0.1"), [42, 0],
                           WAIT_S, READ_S) == [42, 0]
    finally:
        down = _softplc(tmp_path, "plant", "down", "plant.toml", "--state-dir", str(state))
    assert down.returncode == 0, down.stderr
    assert "master: stopped" in down.stdout and "peer: already gone" in down.stdout
    assert _leftovers(t) == []  # no namespace, veth or process
    assert not (state / f"sp{t}.json").exists()


# ---- the shipped example: the belt as a host of its own (the plant host) --------------
EXAMPLE = ROOT / "ladder_programs" / "plant" / "plant.toml"
LINE_S = 60.0  # bounds a failing test only: boxes fed every 3 s, filled 1.5 s, capped 0.5 s


def _leftovers(t: str) -> list[str]:
    """Namespaces, interfaces and processes of plant `t` still there."""
    ns = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    links = subprocess.run(["ip", "-o", "link"], capture_output=True, text=True).stdout
    ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    return [line for text in (ns, links, ps) for line in text.splitlines()
            if f"sp{t}" in line or f"v{t}" in line]


def test_plant_up_carries_the_belt_and_a_broken_wire_reads_0(tmp_path):
    from softplc.commands.io import Client, IoError
    from softplc.runtime.wiretcp import HOLD_S

    state = tmp_path / "state"
    t = hosts.tag(EXAMPLE)
    up = _softplc(tmp_path, "plant", "up", str(EXAMPLE), "--netns", "--state-dir",
                  str(state), "--web", "0")
    try:
        assert up.returncode == 0, up.stderr
        record = json.loads((state / f"sp{t}.json").read_text())
        assert record["processes"]["plant"]["host"] == "10.0.35.252"
        if not record["root"]:
            pytest.skip("this machine has an address in 10.0.35.0/24 already")
        # from this machine (the root namespace's veth): each controller's web API
        master, filler = (Client(record["controllers"][n]["host"], hosts.WEB_PORT,
                                 record["token"]) for n in ("master", "filler"))
        # a wired input is the plant host's: the monitor may force it, not write it
        with pytest.raises(IoError, match="driven by the plant host's wire"):
            master.set("%I0.1", 1)
        master.set("%I0.0", 1)  # the line on switch
        # the belt runs (the master's motor output, through the plant host) and boxes are
        # filled and capped: the master's counters of the stations' reports move
        assert until_equal(lambda: min(master.get("%MW1", "%MW2").values()) >= 1, True,
                           LINE_S, 0.5)
        assert filler.get("%I0.5")["%I0.5"] == 1  # the line enable, master %Q0.2
        # the plant host's cable cut (its veth down): silent, the wired inputs read 0
        # after HOLD_S (a frame timeout), the unwired ones keep their value
        plant_ns = record["processes"]["plant"]["namespace"]
        veth = subprocess.run(["ip", "-n", plant_ns, "-o", "link", "show", "type", "veth"],
                              capture_output=True, text=True).stdout.split(":")[1].strip()
        veth = veth.split("@")[0]
        subprocess.run(["ip", "-n", plant_ns, "link", "set", veth, "down"], check=True)
        assert until_equal(lambda: filler.get("%I0.5")["%I0.5"], 0, WAIT_S + HOLD_S,
                           READ_S) == 0
        assert master.get("%I0.0")["%I0.0"] == 1
        subprocess.run(["ip", "-n", plant_ns, "link", "set", veth, "up"], check=True)
        assert until_equal(lambda: filler.get("%I0.5")["%I0.5"], 1, WAIT_S, READ_S) == 1
        # the plant host killed: its connections end, the wired inputs read 0 at once
        os.killpg(record["processes"]["plant"]["pid"], signal.SIGKILL)
        assert until_equal(lambda: filler.get("%I0.5")["%I0.5"], 0, WAIT_S, READ_S) == 0
        # a controller killed: the others run on
        os.killpg(record["controllers"]["capper"]["pid"], signal.SIGKILL)
        assert master.status()["state"] == "RUN"
    finally:
        down = _softplc(tmp_path, "plant", "down", str(EXAMPLE), "--state-dir", str(state))
    assert down.returncode == 0, down.stderr
    assert "capper: already gone" in down.stdout and "plant: already gone" in down.stdout
    assert _leftovers(t) == []
