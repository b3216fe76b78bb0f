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
from pathlib import Path

import pytest
from waits import until_equal

from softplc.plant import hosts

ROOT = Path(__file__).resolve().parents[2]
WHY = hosts.netns_works()
pytestmark = pytest.mark.skipif(bool(WHY), reason=f"network namespaces: {WHY}")
WAIT_S = 15.0  # bounds a failing test only
READ_S = 0.1  # between reads: each starts a process in the SCADA's namespace

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
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "softplc", *args], cwd=tmp, env=env,
                          capture_output=True, text=True, timeout=120)


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
    up = _softplc(tmp_path, "plant", "up", "plant.toml", "--netns", "--state-dir", str(state))
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
    left = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert f"sp{t}" not in left
    assert not (state / f"sp{t}.json").exists()
