"""`softplc tune --port`: the online mode against the daemon on loopback (a tiny IL program
raises the request), and its wait for a daemon that is not listening yet."""

from __future__ import annotations

import threading

import pytest
from daemon_util import Daemon

from softplc.cli import main
from softplc.machines.machining import handshake, tuning
from softplc.machines.machining.mpfile import MPFile
from softplc.modbus.host import ModbusHost

PROGRAM = """\
(*RUNG: the softkey (%M10, written by the host test) raises an estimation request*)
LD    %M10
[ %MW401 := %MW401 + 1 ]
LD    %M10
R     %M10
(*RUNG: acknowledged with status 0: apply MP2500 (%MF420) to the axis (%MF500)*)
LD    [ %MW402 = %MW401 ]
AND   [ %MW403 = 0 ]
AND   [ %MW401 <> 0 ]
[ %MF500 := %MF420 ]
"""


def _press(port: int) -> None:
    with ModbusHost("127.0.0.1", port) as h:
        h._call("softkey", lambda c, **kw: c.write_coil(10, True, **kw))


def _tune_once(args: list[str]) -> tuple[threading.Thread, list[int]]:
    rc: list[int] = []
    t = threading.Thread(target=lambda: rc.append(main(["tune", *args, "--once",
                                                        "--wait", "20", "--poll", "0.02"])))
    t.start()
    return t, rc


def test_online_request_over_modbus(tmp_path, capsys):
    d = tmp_path / "files"
    tuning.write_example(d, mass=22699.0, seed=4)
    good = (d / "settings.txt").read_text()
    (d / "settings.txt").write_text(good.replace("Acc_uncert = 0.05", "Acc_uncert = 1e-06"))
    daemon = Daemon(tmp_path, program=PROGRAM)
    try:
        port = str(daemon.port)
        # 1: a refusal (u/m > Acc_uncert): status 5, nothing applied, nothing written
        t, rc = _tune_once(["--dir", str(d), "--port", port])
        _press(daemon.port)
        t.join(30)
        assert rc == [1]
        with ModbusHost("127.0.0.1", daemon.port) as h:
            req, ack, status = h.read_words(handshake.W_REQ, 3)
            assert (req, ack, status) == (1, 1, 5)
            assert h.read_float(handshake.F_MPS) == 0.0 and h.read_float(500) == 0.0
        assert not (d / "MPSet.H").exists()
        # 2: accepted: the words, EST_ACK, and the PLC applies MP2500 of row 2
        (d / "settings.txt").write_text(good)
        t, rc = _tune_once(["--dir", str(d), "--port", port])
        _press(daemon.port)
        t.join(30)
        assert rc == [0]
        with ModbusHost("127.0.0.1", daemon.port) as h:
            for _ in range(100):  # the PLC applies at its next scan
                if h.read_float(500) != 0.0:
                    break
                threading.Event().wait(0.02)
            req, ack, status, row, axis = h.read_words(handshake.W_REQ, 5)
            assert (req, ack, status, row, axis) == (2, 2, 0, 2, 0)
            assert abs(h.read_float(handshake.F_MASS) / 22699 - 1) < 0.01
            assert h.read_float(handshake.F_ACCEL) == pytest.approx(0.22, rel=1e-3)
            assert h.read_float(500) == 3650.0
        assert MPFile.read(d / "MPSet.H").values()[1] == 3650.0
        err = capsys.readouterr().err
        assert "request 1: status 5" in err and "request 2: status 0" in err
        # 3: no request within --wait: a clear error, nothing written to the PLC
        assert main(["tune", "--dir", str(d), "--port", port, "--once", "--wait", "0.3",
                     "--poll", "0.02"]) == 1
        assert "no estimation request (%MW401 != %MW402)" in capsys.readouterr().err
    finally:
        daemon.stop()


def test_online_waits_for_a_daemon_not_listening_yet(tmp_path, capsys):
    """`tune --port` started before the daemon waits for it (one message), then gives up
    with a clear error after --connect-timeout."""
    import socket

    with socket.socket() as srv:  # bound, not listening: refused; no parallel worker takes it
        srv.bind(("127.0.0.1", 0))
        port = srv.getsockname()[1]
        assert main(["tune", "--dir", str(tmp_path), "--port", str(port), "--once",
                     "--connect-timeout", "0.3"]) == 1
        err = capsys.readouterr().err
        assert err.count("waiting up to 0.3 s for the PLC at 127.0.0.1:") == 1
        assert "cannot reach the PLC" in err
        # a listener that comes up after the first refusals is reached
        seen: list[str] = []
        timer = threading.Timer(0.4, srv.listen)
        timer.start()
        try:
            host = ModbusHost("127.0.0.1", port).connect_within(10, seen.append)
            host.close()
        finally:
            timer.join()
    assert len(seen) == 1 and "waiting up to 10 s" in seen[0]
