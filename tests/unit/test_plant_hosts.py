"""`plant up`'s command lines and addresses (softplc.plant.hosts), without namespaces."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.errors import PlantStateError
from softplc.plant import hosts
from softplc.plant.model import load_plant

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
