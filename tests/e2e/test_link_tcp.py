"""The Remote Link over TCP between `softplc run` daemons (issue 35, softplc.runtime.linktcp):
words both ways, a killed peer seen by the master within MISSES link cycles, a restarted
peer rejoining without restarting the master, bad frames refused."""

from __future__ import annotations

import re
import signal
import socket
from pathlib import Path

import pytest
from waits import until_equal

from softplc.plc import PLC
from softplc.runtime import linktcp
from softplc.runtime.remotelink import ERR_TIMEOUT, MISSES, SW_LINK_ERROR, SW_LINK_STATUS
from tests.daemon_util import daemons, started  # noqa: F401  (the fixture)

PEER_IL = """
LD 1
[ %QNW0.0 := %INW0.0 + 1 ]
[ %MW0 := %INW0.0 ]
[ %MW1 := %SW111 ]
"""
MASTER_IL = """
LD 1
[ %QNW1.0 := %MW10 ]
[ %MW0 := %INW1.0 ]
[ %MW1 := %SW111 ]
[ %MW2 := %SW112 ]
"""
MASTER_TOML = """
scan_period = "10ms"
[remote_link]
address = 0
remotes = { 1 = "peer" }
cycle = "20ms"
"""
PEER_TOML = """
scan_period = "10ms"
[remote_link]
address = 1
"""


def _files(tmp: Path) -> tuple[Path, Path]:
    (tmp / "master").mkdir()
    (tmp / "peer").mkdir()
    (tmp / "master" / "master.toml").write_text(MASTER_TOML)
    (tmp / "peer" / "peer.toml").write_text(PEER_TOML)
    return tmp / "master", tmp / "peer"


def test_two_daemons_exchange_words_and_survive_a_peer_restart(daemons, tmp_path):  # noqa: F811
    mdir, pdir = _files(tmp_path)
    peer = started(daemons, pdir, "--config", "peer.toml",  # port 0: parallel workers
                   "--link-listen", "127.0.0.1:0", program=PEER_IL)
    said = next(ln for ln in peer.out if "answering polls on 127.0.0.1:" in ln)
    link_port = int(re.search(r"127\.0\.0\.1:(\d+) \(TCP\)", said)[1])
    master = started(daemons, mdir, "--config", "master.toml",
                     "--link-remote", f"1=127.0.0.1:{link_port}", program=MASTER_IL)
    assert any("Remote Link: master, every 20 ms" in ln for ln in master.out)
    mc, pc = master.client(), peer.client()
    mc.write_registers(10, [41])
    # the master's %QNW1.0 reaches the peer's %INW0.0; the peer's answer comes back
    assert until_equal(lambda: pc.read_registers(0, 2), [41, 1]) == [41, 1]
    assert until_equal(lambda: mc.read_registers(0, 3), [42, 1, 0]) == [42, 1, 0]

    peer.kill()  # SIGKILL: no goodbye on the link
    assert until_equal(lambda: mc.read_registers(1, 2), [0, ERR_TIMEOUT]) == [0, ERR_TIMEOUT]
    assert mc.read_registers(0, 1) == [42]  # the last words are held (HOLD_LAST_VALUES)

    peer2 = started(daemons, pdir, "--config", "peer.toml",
                    "--link-listen", f"127.0.0.1:{link_port}", program=PEER_IL)
    mc.write_registers(10, [7])
    assert until_equal(lambda: mc.read_registers(0, 3), [8, 1, 0]) == [8, 1, 0]  # rejoined
    assert master.proc.poll() is None  # the same master process all along
    p2 = peer2.client()
    assert until_equal(lambda: p2.read_registers(0, 2), [7, 1]) == [7, 1]

    master.stop(signal.SIGINT)  # the peer sees its master go silent
    assert until_equal(lambda: p2.read_registers(1, 1), [0]) == [0]
    for c in (mc, pc, p2):
        c.close()


def _plc(il: str, toml: str, tmp: Path, name: str) -> PLC:
    cfg = tmp / f"{name}.toml"
    cfg.write_text(toml)
    return PLC.from_source(il, cfg)


def test_a_killed_peer_is_absent_after_misses_link_cycles(tmp_path):
    """Cycle by cycle (run_cycle, the link thread's step, driven by hand): MISSES cycles
    without an answer clear the master's %SW111 bit at its next scan, not earlier."""
    master = _plc(MASTER_IL, MASTER_TOML, tmp_path, "m")
    peer = _plc(PEER_IL, PEER_TOML, tmp_path, "p")
    remote = linktcp.RemoteService(peer.machine.link, "127.0.0.1", 0)
    remote.attach(peer)
    remote.start()
    svc = linktcp.MasterService(master.machine.link, {1: remote.address})
    svc.attach(master)
    try:
        master.mem.mw.w[10] = 5
        master.scan()
        for _ in range(3):
            svc.run_cycle()
            master.scan()
            until_equal(lambda: remote.polls >= svc.cycles, True)
            peer.scan()
        assert master.mem.sw.uw[SW_LINK_STATUS] == 1
        assert master.mem.mw.w[0] == 6
        remote.stop()  # the peer's process is gone: its port refuses
        for missed in range(1, MISSES + 1):
            svc.run_cycle()
            master.scan()
            gone = master.mem.sw.uw[SW_LINK_STATUS] == 0
            assert gone == (missed >= MISSES), missed
        assert master.mem.sw.uw[SW_LINK_ERROR] == ERR_TIMEOUT
    finally:
        svc.stop()
        remote.stop()


@pytest.mark.parametrize("frame", [
    b"XX" + bytes(linktcp.HEADER.size - 2),                     # not the magic
    linktcp.HEADER.pack(b"TL", 9, linktcp.POLL, 1, 1, 20, 0),    # another version
    linktcp.HEADER.pack(b"TL", 1, linktcp.POLL, 1, 1, 20, 200),  # too many words
    linktcp.HEADER.pack(b"TL", 1, linktcp.POLL, 1, 1, 0, 0),     # no cycle: a busy tick
    linktcp.HEADER.pack(b"TL", 1, linktcp.POLL, 2, 1, 20, 0),    # another station
])
def test_a_remote_closes_on_a_bad_frame_and_keeps_serving(tmp_path, frame):
    peer = _plc(PEER_IL, PEER_TOML, tmp_path, "p")
    remote = linktcp.RemoteService(peer.machine.link, "127.0.0.1", 0)
    remote.attach(peer)
    remote.start()
    try:
        with socket.create_connection(remote.address, timeout=5) as s:
            s.sendall(frame)
            assert s.recv(64) == b""  # closed without an answer
        good = linktcp.encode_poll(1, "peer", 20_000, linktcp.Request(words=(3, 0, 0, 0)))
        with socket.create_connection(remote.address, timeout=5) as s:
            s.sendall(good)
            address, kind, _, items = linktcp.read_frame(s, linktcp.ANSWER)
        assert (address, kind, len(items)) == (1, linktcp.WORDS, 4)
    finally:
        remote.stop()


def test_bad_link_options_are_refused_with_a_reason(tmp_path):
    from softplc.errors import SoftPLCError

    master = _plc(MASTER_IL, MASTER_TOML, tmp_path, "m")
    with pytest.raises(SoftPLCError, match="remote 1 is declared .* no ADDR=HOST:PORT"):
        linktcp.MasterService(master.machine.link, {})
    with pytest.raises(ValueError, match="HOST:PORT"):
        linktcp.endpoint("127.0.0.1:99999")


def test_a_new_master_connection_replaces_the_old_one(tmp_path):
    """A restarted master reconnects: the remote answers the new connection and hangs up
    the old one (one master per link)."""
    peer = _plc(PEER_IL, PEER_TOML, tmp_path, "p")
    remote = linktcp.RemoteService(peer.machine.link, "127.0.0.1", 0)
    remote.attach(peer)
    remote.start()
    poll = linktcp.encode_poll(1, "peer", 20_000, linktcp.Request(words=(1, 0, 0, 0)))
    try:
        with socket.create_connection(remote.address, timeout=5) as old:
            old.sendall(poll)
            assert linktcp.read_frame(old, linktcp.ANSWER)[0] == 1
            with socket.create_connection(remote.address, timeout=5) as new:
                new.sendall(poll)
                assert linktcp.read_frame(new, linktcp.ANSWER)[0] == 1
                assert old.recv(64) == b""  # hung up
                new.sendall(poll)
                assert linktcp.read_frame(new, linktcp.ANSWER)[0] == 1
    finally:
        remote.stop()
