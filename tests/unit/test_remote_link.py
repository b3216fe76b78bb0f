"""The Twido Remote Link objects (issue 35): %INWi.j / %QNWi.j, [remote_link], the
exchange over the in-memory transport, the status words %SW111-%SW113."""

from __future__ import annotations

import pytest

from softplc.config import validate_config
from softplc.errors import AddressError, ConfigError, ProgramError
from softplc.modbus.tags import build as build_tags
from softplc.plc import PLC
from softplc.runtime.remotelink import (
    ERR_MISMATCH,
    ERR_NONE,
    ERR_TIMEOUT,
    MISSES,
    SW_LINK_CONFIG,
    SW_LINK_ERROR,
    SW_LINK_STATUS,
    InMemoryTransport,
    LinkMaster,
    LinkRemote,
)
from softplc.twido.address import parse_address

MASTER_CFG = {"remote_link": {"address": 0, "remotes": {"1": "peer", "3": "peer"}}}


def peer_cfg(address: int) -> dict:
    return {"remote_link": {"address": address}}


# ---- addresses -------------------------------------------------------------------------------
def test_network_word_addresses():
    r = parse_address("%INW3.2")
    assert (r.kind, r.module, r.channel, r.index, r.type, r.writable) == \
        ("INW", 3, 2, 14, "int16", False)
    q = parse_address("%qnw0.3")
    assert (q.kind, q.index, q.writable, str(q)) == ("QNW", 3, True, "%QNW0.3")
    assert str(parse_address("%INW7.0")) == "%INW7.0"


@pytest.mark.parametrize("text", ["%INW8.0", "%INW1.4", "%QNW1", "%INW1.0:X3", "%QNW1.0:2"])
def test_network_word_addresses_refused(text):
    with pytest.raises(AddressError, match="Remote Link words"):
        parse_address(text)


# ---- configuration ---------------------------------------------------------------------------
def test_remote_link_config():
    cfg = validate_config(MASTER_CFG).remote_link
    assert cfg.kind == "master" and cfg.remotes == {1: "peer", 3: "peer"}
    assert validate_config(peer_cfg(2)).remote_link.kind == "peer"


@pytest.mark.parametrize(("section", "message"), [
    ({"address": 0}, "the master declares its remotes"),
    ({"address": 8}, "remote_link.address: expected less than or equal to 7"),
    ({"address": 0, "remotes": {"9": "peer"}}, "remote_link.remotes.9: a remote's address"),
    ({"address": 2, "remotes": {"1": "peer"}}, r"the master's \(address 0\) settings"),
    ({"address": 2, "role": "master"}, "does not go with address 2"),
    ({"address": 0, "role": "remote_io", "remotes": {"1": "peer"}}, "does not go with address 0"),
    ({"address": 1, "speed": 9600}, "remote_link.speed: unknown key"),
])
def test_remote_link_config_errors(section, message):
    with pytest.raises(ConfigError, match=message):
        validate_config({"remote_link": section})


# ---- programs --------------------------------------------------------------------------------
def test_program_reads_and_writes_network_words():
    plc = PLC.from_source("LD 1\n[ %QNW1.0 := %INW3.2 + 1 ]\n", MASTER_CFG)
    plc["%INW3.2"] = 41
    plc.scan()
    assert plc["%QNW1.0"] == 42
    assert plc["%SW113"] == 0b101  # remotes 1 and 3 declared


@pytest.mark.parametrize(("source", "config", "message"), [
    ("LD 1\n[ %QNW2.0 := 1 ]\n", MASTER_CFG, "station 2 is not a peer of this master"),
    ("LD 1\n[ %INW1.0 := 1 ]\n", MASTER_CFG, "cannot write %INW1.0"),
    ("LD 1\n[ %QNW1.0 := 1 ]\n", peer_cfg(1), "a peer exchanges words with the master only"),
    ("LD 1\n[ %MW0 := %INW0.0 ]\n", None, "the Remote Link is not configured"),
])
def test_program_network_word_errors(source, config, message):
    with pytest.raises(ProgramError, match=message) as e:
        PLC.from_source(source, config)
    assert e.value.diagnostics[0].line == 2


def test_modbus_map_lists_network_words_as_hidden():
    plc = PLC.from_source("LD 1\n[ %MW0 := %INW1.0 ]\n[ %QNW1.1 := %MW0 ]\n", MASTER_CFG)
    hidden = {h.address: h.why for h in build_tags(plc.ast).hidden}
    assert "copy it ([ %MW1 := %INW1.0 ])" in hidden["%INW1.0"] and "%QNW1.1" in hidden


# ---- the exchange ----------------------------------------------------------------------------
def _line() -> tuple[PLC, PLC, InMemoryTransport]:
    master = PLC.from_source("LD 1\n[ %QNW1.0 := %MW0 ]\n[ %MW1 := %INW1.0 ]\n",
                             {"remote_link": {"address": 0, "remotes": {"1": "peer"}}})
    peer = PLC.from_source("LD 1\n[ %QNW0.0 := %INW0.0 * 2 ]\n", peer_cfg(1))
    t = InMemoryTransport()
    assert isinstance(master.machine.link, LinkMaster)
    assert isinstance(peer.machine.link, LinkRemote)
    master.machine.link.transport = t
    t.attach(peer.machine.link)
    return master, peer, t


def _cycle(master: PLC, t: InMemoryTransport) -> None:
    for r in t.remotes():
        r.tick()
    master.machine.link.cycle()


def test_master_and_peer_exchange_four_words_each_way():
    master, peer, t = _line()
    master["%MW0"] = 21
    master.scan()          # %QNW1.0 := 21
    _cycle(master, t)      # -> peer %INW0.0
    peer.scan()            # %QNW0.0 := 42
    _cycle(master, t)      # -> master %INW1.0
    master.scan()
    assert (peer["%INW0.0"], master["%INW1.0"], master["%MW1"]) == (21, 42, 42)
    assert master["%SW111"] & 1 and master["%SW112"] == ERR_NONE
    assert peer["%SW111"] == 1 and peer["%SW113"] == 1  # its own address 1: bit 0


def test_a_lost_peer_is_seen_within_misses_cycles_and_rejoins():
    master, peer, t = _line()
    _cycle(master, t)
    assert master.machine.link.present(1)
    t.detach(1)
    for n in range(1, MISSES + 1):
        _cycle(master, t)
        assert master.machine.link.present(1) == (n < MISSES)
    assert master.mem.sw.uw[SW_LINK_ERROR] == ERR_TIMEOUT
    assert master.mem.sw.uw[SW_LINK_STATUS] == 0 and master.mem.sw.uw[SW_LINK_CONFIG] == 1
    t.attach(peer.machine.link)
    _cycle(master, t)
    assert master.machine.link.present(1) and master.mem.sw.uw[SW_LINK_ERROR] == ERR_NONE


def test_a_peer_sees_its_master_go():
    master, peer, t = _line()
    _cycle(master, t)
    remote = peer.machine.link
    remote.tick()  # closes the cycle in which the master polled
    assert peer["%SW111"] == 1
    for _ in range(MISSES):  # the master polls no more: the peer's own cycles tick on
        remote.tick()
    assert peer["%SW111"] == 0 and peer["%SW112"] == ERR_TIMEOUT


def test_a_slowed_link_delays_the_words_and_stays_healthy():
    master, peer, t = _line()
    t.delay(1, 2)
    peer.mem.qnw.w[0] = 7
    seen = []
    for _ in range(6):
        _cycle(master, t)
        seen.append(master["%INW1.0"])
    assert seen == [0, 0, 7, 7, 7, 7]  # two cycles late
    assert master.machine.link.present(1)


def test_a_cut_line_is_an_absent_remote():
    master, peer, t = _line()
    peer.mem.qnw.w[0] = 5
    _cycle(master, t)
    t.cut(1)
    for _ in range(MISSES):
        _cycle(master, t)
    peer.mem.qnw.w[0] = 6
    _cycle(master, t)
    assert not master.machine.link.present(1)
    assert master["%INW1.0"] == 5  # the last good words are held
    t.mend(1)
    _cycle(master, t)
    assert master.machine.link.present(1) and master["%INW1.0"] == 6


def test_a_remote_of_another_type_is_a_configuration_mismatch():
    master, peer, t = _line()
    t.attach(LinkRemote(peer.mem, 1, role="remote_io"))  # declared a peer by the master
    _cycle(master, t)
    assert not master.machine.link.present(1)
    assert master.mem.sw.uw[SW_LINK_ERROR] == ERR_MISMATCH


# ---- remote I/O controllers ------------------------------------------------------------------
RIO_MASTER = {"remote_link": {"address": 0, "remotes": {"1": "peer", "3": "remote_io"}}}


def test_remote_io_addresses():
    r = parse_address("%I3.0.2")
    assert (r.kind, r.station, r.module, r.channel, str(r)) == ("I", 3, 0, 2, "%I3.0.2")
    assert r != parse_address("%I0.2") and r.index != parse_address("%I3.2").index
    assert str(parse_address("%q7.0.15")) == "%Q7.0.15"


@pytest.mark.parametrize("text", ["%I8.0.1", "%I0.0.1", "%I1.1.0", "%I1.0.24", "%Q1.0.16",
                                  "%I1.0.1:X2", "%Q1.0.0:2"])
def test_remote_io_addresses_refused(text):
    with pytest.raises(AddressError, match="remote I/O"):
        parse_address(text)


@pytest.mark.parametrize(("source", "config", "message"), [
    ("LD %I1.0.0\nST %Q0.0\n", RIO_MASTER, "station 1 is not a remote I/O of this master"),
    ("LD %I0.0\nST %Q2.0.0\n", RIO_MASTER, "station 2 is not a remote I/O of this master"),
    ("LD %I3.0.0\nST %Q0.0\n", peer_cfg(1), "only the master reaches a remote I/O"),
])
def test_remote_io_channel_errors(source, config, message):
    with pytest.raises(ProgramError, match=message):
        PLC.from_source(source, config)


def test_the_master_drives_a_remote_io_controller():
    master = PLC.from_source("LD %I3.0.2\nST %Q3.0.1\n", RIO_MASTER)
    rio = PLC.from_source("", {"remote_link": {"address": 3, "role": "remote_io"}})
    t = InMemoryTransport()
    master.machine.link.transport = t
    t.attach(rio.machine.link)
    rio["%I0.2"] = 1           # the remote's field input
    master.machine.link.cycle()  # -> the master's %I3.0.2 (latched by its next scan)
    master.scan()              # %Q3.0.1 := %I3.0.2
    master.machine.link.cycle()  # -> the remote's output
    assert master["%I3.0.2"] and master["%Q3.0.1"]
    assert rio.mem.q_field[1] and rio["%Q0.1"]
    assert "%I3.0.2" in repr(master) and master["%SW111"] == 0b100
