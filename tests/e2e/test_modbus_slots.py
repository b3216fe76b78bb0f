"""Issue 21, Modbus server: a few hostile sockets must not lock clients out.

Each attack keeps 8 connections to a server with `max_clients=8` and every other setting
at its default (60 s idle timeout, 2 s frame deadline), reopening each connection the
server closes; a legitimate client must still be answered (target: within 30 s; the
attackers come from `tools/bench_slots.py`, which prints the same figures against the
daemon)."""

from __future__ import annotations

import socket
import struct
import sys
import time
from pathlib import Path

import pytest

from softplc.modbus import ModbusImage, ServerThread
from softplc.modbus import server as srv
from softplc.modbus.rawclient import RawClient
from softplc.modbus.server import DEFAULT_IDLE_TIMEOUT
from softplc.modbus_codec import frame as mbap_frame
from softplc.runtime.memory import MemoryImage

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))

from bench_slots import Attack, first_answer  # noqa: E402
from modbus_util import closed_or_reply  # noqa: E402
from waits import until  # noqa: E402


@pytest.fixture
def server():
    mem = MemoryImage()
    mem.mw.w[0] = 1234
    th = ServerThread(ModbusImage(mem), "127.0.0.1", 0, max_clients=8).start()
    yield th
    th.stop()


@pytest.mark.parametrize("kind", ["idle", "slowloris", "never-reading"])
def test_a_client_is_answered_under_attack_with_defaults(server, kind):
    assert server.server.idle_timeout == DEFAULT_IDLE_TIMEOUT > 0
    with Attack(kind, server.port, drip=0.2) as atk:
        assert atk.held.wait(10)  # all 8 slots taken (the attack works)
        time.sleep(0.3)
        got = first_answer(server.port, limit=30)
        assert got is not None
        with got[1] as c:  # and the client keeps its slot while it polls
            for _ in range(5):
                time.sleep(0.1)
                assert c.read_registers(0, 1) == [1234]


def test_clients_that_talk_keep_their_slots_against_connection_churn(server):
    """Eviction takes connections that never completed a request first: 7 polling
    clients keep their slots while hostile connections come and go in the eighth."""
    clients = [RawClient("127.0.0.1", server.port, timeout=5) for _ in range(7)]
    try:
        for c in clients:
            assert c.read_registers(0, 1) == [1234]
        with Attack("idle", server.port, n=4):
            for _ in range(30):
                for c in clients:
                    assert c.read_registers(0, 1) == [1234]
                time.sleep(0.05)
        assert server.server.stats.evicted > 0
    finally:
        for c in clients:
            c.close()


def test_eviction_order(monkeypatch):
    """Table full: unread replies go first, then a connection that completed no request
    within EVICT_GRACE, then the longest idle past EVICT_IDLE; else the newcomer is
    refused (a storm cannot push out clients that poll)."""
    monkeypatch.setattr(srv, "EVICT_IDLE", 0.4)
    monkeypatch.setattr(srv, "EVICT_GRACE", 0.8)
    th = ServerThread(ModbusImage(MemoryImage()), "127.0.0.1", 0, max_clients=2).start()
    try:
        with RawClient("127.0.0.1", th.port) as b:
            a = socket.create_connection(("127.0.0.1", th.port))  # connected, silent
            assert b.read_registers(0, 1) == [0]
            with pytest.raises(OSError):  # a is young: c is refused (reset)
                with RawClient("127.0.0.1", th.port) as c:
                    c.read_registers(0, 1)
            time.sleep(srv.EVICT_GRACE + 0.1)
            assert b.read_registers(0, 1) == [0]  # b talks: not idle
            with RawClient("127.0.0.1", th.port) as c:  # a had its chance: c takes it
                assert c.read_registers(0, 1) == [0]
                assert closed_or_reply(a) == b""
                a.close()
                assert b.read_registers(0, 1) == [0]  # b talks: kept
                time.sleep(0.2)
                assert b.read_registers(0, 1) == [0]
                time.sleep(0.3)  # c idle 0.5 s, b 0.3 s
                with RawClient("127.0.0.1", th.port) as e:
                    assert e.read_registers(0, 1) == [0]
                    assert b.read_registers(0, 1) == [0]
                    with pytest.raises(OSError):
                        c.read_registers(0, 1)
        assert th.stats.evicted == 2 and th.stats.rejected == 1
    finally:
        th.stop()


def test_a_client_leaving_replies_unread_is_evicted_first():
    th = ServerThread(ModbusImage(MemoryImage()), "127.0.0.1", 0, max_clients=2).start()
    try:
        with RawClient("127.0.0.1", th.port) as b:
            assert b.read_registers(0, 1) == [0]
            u = socket.create_connection(("127.0.0.1", th.port))
            u.sendall(mbap_frame(1, 1, struct.pack(">BHH", 3, 0, 125)) * 2000)  # 518 kB out
            def unread() -> list:  # u's connection once it holds replies unread
                return [c for c in list(th.server.connections) if c.peer[1] ==
                        u.getsockname()[1] and c.unread() > srv.UNREAD_EVICT]

            until(unread)  # at the server's own pace, not after a fixed 0.3 s
            (conn,) = unread()
            with RawClient("127.0.0.1", th.port) as n:  # u has completed requests, but
                assert n.read_registers(0, 1) == [0]  # does not read: its slot goes
                assert b.read_registers(0, 1) == [0]
            assert th.stats.evicted == 1 and conn not in th.server.connections
            u.settimeout(2)
            try:
                while u.recv(1 << 20):  # what was delivered, then the end
                    pass
            except ConnectionResetError:
                pass
            u.close()
    finally:
        th.stop()


def test_frame_deadline_runs_from_the_first_byte():
    """Bytes of a frame do not restart its deadline: a request dripped one byte per
    50 ms (complete after 0.55 s) is closed at the 0.3 s deadline, unanswered."""
    th = ServerThread(ModbusImage(MemoryImage()), "127.0.0.1", 0, frame_timeout=0.3).start()
    try:
        s = socket.create_connection(("127.0.0.1", th.port))
        frame = mbap_frame(1, 1, struct.pack(">BHH", 3, 0, 1))
        got = b""
        try:
            for k in range(len(frame)):
                s.sendall(frame[k:k + 1])
                time.sleep(0.05)
            s.settimeout(2)
            got = s.recv(100)
        except OSError:  # reset while dripping: closed as well
            pass
        assert got == b""
        assert th.stats.dropped == 1
        s.close()
    finally:
        th.stop()


def test_accepted_sockets_have_keepalive(server):
    with RawClient("127.0.0.1", server.port) as c:
        c.read_registers(0, 1)
        (conn,) = server.server.connections
        sock = conn.transport.get_extra_info("socket")
        assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) == 1
        if hasattr(socket, "TCP_KEEPIDLE"):
            assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE) == 30


@pytest.mark.parametrize("section, message", [
    ({"max_clients": 2**63}, "modbus.max_clients: expected less than or equal to 1000"),
    ({"max_clients": 0}, "modbus.max_clients"),
    ({"frame_timeout": "0s"}, "modbus.frame_timeout: must be from 0.1 s to 60 s"),
    ({"frame_timeout": "2min"}, "modbus.frame_timeout"),
    ({"idle_timeout": "10ms"}, "modbus.idle_timeout: must be from 1 s to 86400 s (0: never)"),
])
def test_modbus_numbers_are_bounded(section, message):
    from softplc.errors import ConfigError
    from softplc.plc import PLC

    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.0\n", {"modbus": section})
    assert message in str(e.value)
    PLC.from_source("LD 1\nST %Q0.0\n", {"modbus": {"idle_timeout": "0s"}})  # 0 = never


@pytest.mark.parametrize("flag, value, message", [
    ("--max-clients", str(2**63), "a whole number from 1 to 1000"),
    ("--idle-timeout", "0.01", "must be from 1 s to 86400 s"),
    ("--frame-timeout", "0", "must be from 0.1 s to 60 s"),
])
def test_daemon_flags_are_bounded(tmp_path, capsys, flag, value, message):
    from softplc.cli import main

    prog = tmp_path / "p.il"
    prog.write_text("LD 1\nST %Q0.0\n")
    with pytest.raises(SystemExit) as e:
        main(["run", str(prog), flag, value])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
