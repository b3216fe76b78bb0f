"""Issue 9, daemon side: nothing lost, nothing unbounded, stoppable, protected.

Subprocess tests of `softplc run` (real clock, loopback TCP, real signals)."""

from __future__ import annotations

import os
import signal
import socket
import struct
import sys
import time
from pathlib import Path

import pytest
from daemon_util import Daemon, started
from waits import WAIT_S, until
from zygote import popen

from softplc.modbus.rawclient import ModbusExceptionReply, RawClient
from softplc.persist import retain

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import bench_kill  # noqa: E402

PROGRAM = "LD 1\n[ %MW12 := %MW12 + 1 ]\nEND\n"  # %MW12 counts scans
# %MW20 shows %TM0's preset.
TIMER_PROGRAM = """\
LD    1
[ %MW12 := %MW12 + 1 ]
BLK   %TM0
LD    %M1
IN
OUT_BLK
LD    Q
ST    %M2
END_BLK
LD    1
[ %MW20 := %TM0.P ]
END
"""
TIMER = '[timers."%TM0"]\ntype = "TON"\nbase = "100ms"\npreset = {}\n'


def start(daemons, tmp, *args, **kw) -> Daemon:
    kw.setdefault("program", PROGRAM)
    return started(daemons, tmp, *args, **kw)


def failed_start(daemons, tmp, *args, **kw) -> str:
    """Start a daemon that must refuse to run; its stderr."""
    d = start(daemons, tmp, *args, wait=False, **kw)
    assert d.proc.wait(20) == 1
    err = d.stderr()
    assert "Traceback" not in err
    return err


# -- 1, 2: a second daemon harms nothing ------------------------------------------------------
def test_second_daemon_on_same_port_leaves_the_trace_alone(daemons, tmp_path):
    table = ROOT / "ladder_programs"
    args = ("--config", str(table / "drawing_table.toml"), "--trace", "t.csv")
    d = start(daemons, tmp_path, *args, program=table / "drawing_table.il")
    trace = tmp_path / "t.csv"
    until(lambda: trace.exists() and trace.read_text().count("\n") >= 3)
    before = trace.read_text()
    err = failed_start(daemons, tmp_path, *args, "--port", str(d.port),
                       program=table / "drawing_table.il")
    assert trace.read_text().startswith(before)  # nothing truncated
    assert "cannot listen" in err and "--port" in err
    err = failed_start(daemons, tmp_path, *args, program=table / "drawing_table.il")
    assert "trace file" in err and "in use by another softplc" in err  # another port
    assert trace.read_text().startswith(before)
    assert d.stop() == 0
    assert trace.read_text().startswith(before)


def test_second_daemon_on_same_state_file_refuses(daemons, tmp_path):
    state = tmp_path / "plc.state"
    table = ROOT / "ladder_programs"
    d = start(daemons, tmp_path, "--state", str(state))
    with d.client() as c:
        c.write_registers(5, [4242])
    err = failed_start(daemons, tmp_path, "--state", str(state), "--trace", "t.csv",
                       "--config", str(table / "drawing_table.toml"),
                       program=table / "drawing_table.il")
    assert "in use by another softplc" in err and f"pid {d.proc.pid}" in err
    assert not (tmp_path / "t.csv").exists()
    with d.client() as c:
        c.write_registers(6, [4343])
    assert d.stop() == 0
    st = retain.load(state)
    assert struct.unpack_from("<2h", st.mw, 10) == (4242, 4343)


# -- 3: kill -9 -------------------------------------------------------------------------------
def test_kill9_loses_no_acknowledged_write():
    """The short version of tools/bench_kill.py: 5 kills with writes in flight (its daemons
    forked from the test zygote, as the other tests' are)."""
    r = bench_kill.run(kills=5, writers=3, seed=7,
                       launch=lambda argv, cwd: popen(argv, cwd, dict(os.environ)))
    assert r["acknowledged_writes"] > 0
    assert r["lost_total"] == 0 and r["leftover_files"] == []


# -- 4: pending writes are bounded ------------------------------------------------------------
WRITES = 3000  # pairs of frames (FC 16 of 120 and of 2 registers) between two scans


def test_slow_scan_coalesces_writes(daemons, tmp_path):
    """The longest period (10 s): thousands of writes before the next scan (about 1 s on a
    quiet machine, under 3 s with 4 test workers and a busy process on 2 cores); the last
    value of each register wins, an FC 16 frame lands whole, and the daemon does not grow."""
    d = start(daemons, tmp_path, "--period", "10000ms", "--rt-priority", "0",
              program="LD 1\n[ %MW12 := %MW12 + 1 ]\n[ %MW300 := %MW200 + %MW201 ]\nEND\n")
    rss = Path(f"/proc/{d.proc.pid}/status")

    def rss_kb() -> int:
        return int(next(ln.split()[1] for ln in rss.read_text().splitlines()
                        if ln.startswith("VmRSS")))

    with d.client() as c:
        until(lambda: c.read_registers(12, 1) == [1])
        c.write_registers(1000, [1] * 120)
        before = rss_kb()
        for k in range(WRITES):
            c.write_registers(1000, [k & 0x7FFF] * 120)
            c.write_registers(200, [k, -k & 0xFFFF])  # always sums to 0
        c.write_registers(5, [77])
        grown = rss_kb() - before
        assert c.read_registers(12, 1) == [1]  # all of it before the second scan
        assert c.read_registers(1000, 2) == [WRITES - 1] * 2  # reads show pending writes
        until(lambda: c.read_registers(12, 1) == [2], timeout=30)
        assert c.read_registers(300, 1) == [0]  # the last frame landed whole
        assert c.read_registers(1000, 120) == [WRITES - 1] * 120
        assert c.read_registers(5, 1) == [77]
    assert d.stop() == 0
    # the old queue kept every frame: 6,000 entries of up to 240 bytes (twice) = ~3 MB
    assert grown < 1000, f"daemon grew by {grown} kB while writes waited for a scan"


# -- 5: a new application is never a silent cold start (issue 31: the start stops) -------------
def test_changed_config_stops_the_start_unless_keep_state_or_cold(daemons, tmp_path):
    cfg = tmp_path / "m.toml"
    state = tmp_path / "plc.state"
    cfg.write_text(TIMER.format(50))
    args = ("--config", str(cfg), "--state", str(state))
    d = start(daemons, tmp_path, *args, program=TIMER_PROGRAM)
    with d.client() as c:
        c.write_registers(5, [77])
        until(lambda: c.read_registers(20, 1) == [50])
    assert d.stop() == 0
    d = start(daemons, tmp_path, *args, program=TIMER_PROGRAM)
    assert "warm start (same program and configuration)" in "".join(d.out)
    assert d.stop() == 0

    cfg.write_text(TIMER.format(7))
    d = start(daemons, tmp_path, *args, "--keep-state", program=TIMER_PROGRAM)
    assert "warm start (program or configuration changed, data kept" in "".join(d.out)
    with d.client() as c:
        until(lambda: c.read_registers(20, 1) == [50])  # the retained preset
        assert c.read_registers(5, 1) == [77]
    assert d.stop() == 0
    cfg.write_text(TIMER.format(8))
    err = failed_start(daemons, tmp_path, *args, program=TIMER_PROGRAM)
    assert "differs in the configuration (timers)" in err, err
    assert "--keep-state" in err and "--cold" in err
    d = start(daemons, tmp_path, *args, "--cold", program=TIMER_PROGRAM)
    assert "cold start (--cold)" in "".join(d.out)
    with d.client() as c:
        until(lambda: c.read_registers(20, 1) == [8])
        assert c.read_registers(5, 1) == [0]
    assert d.stop() == 0


# -- 6: stoppable whatever the program does ---------------------------------------------------
LOOP_PROGRAM = """\
LD    1
[ %MW12 := %MW12 + 1 ]
LD    [ %MW3 = 1 ]
[ %MW13 := %MW13 + 1 ]
JMPCN %L1
%L0:
LD    1
JMP   %L0
%L1:
LD    1
END
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_stops_an_endless_loop_at_once(daemons, tmp_path, sig):
    cfg = tmp_path / "m.toml"
    cfg.write_text('watchdog = "10min"\n')
    state = tmp_path / "plc.state"
    d = start(daemons, tmp_path, "--config", str(cfg), "--state", str(state),
              program=LOOP_PROGRAM)
    with d.client() as c:
        until(lambda: c.read_registers(12, 1)[0] >= 3)
        c.write_registers(3, [1])  # the next scan loops for ever
        time.sleep(0.3)
    t0 = time.monotonic()
    d.proc.send_signal(sig)
    assert d.proc.wait(WAIT_S) == 0  # not 10 minutes (the watchdog)
    stopped = time.monotonic() - t0
    assert "last scan interrupted" in d.wait_for("stopped after")
    st = retain.load(state)
    mw3, mw13 = struct.unpack_from("<h", st.mw, 6)[0], struct.unpack_from("<h", st.mw, 26)[0]
    assert mw3 == 1  # the acknowledged write is kept
    assert mw13 == 0  # the interrupted scan's work is not: last scan boundary
    assert stopped < WAIT_S  # a bound any machine keeps, far below the watchdog


def test_repeated_sigint_during_shutdown(daemons, tmp_path):
    state = tmp_path / "plc.state"
    for _ in range(2):
        d = start(daemons, tmp_path, "--state", str(state), "--period", "1ms")
        with d.client() as c:
            c.write_registers(7, [1234])
        for _ in range(40):  # Ctrl-C held down
            d.proc.send_signal(signal.SIGINT)
            time.sleep(0.002)
        assert d.proc.wait(WAIT_S) == 0
        err = d.stderr()
        assert "Traceback" not in err and "KeyboardInterrupt" not in err
        assert struct.unpack_from("<h", retain.load(state).mw, 14)[0] == 1234


# -- 11: access ---------------------------------------------------------------------------------
def test_read_only_refuses_every_write_with_01(daemons, tmp_path):
    d = start(daemons, tmp_path, "--read-only")
    assert "every write is answered with exception 01" in "".join(d.out)
    with d.client() as c:
        for pdu in (struct.pack(">BHH", 5, 1, 0xFF00), struct.pack(">BHH", 6, 1, 5),
                    struct.pack(">BHHBB", 15, 0, 1, 1, 1),
                    struct.pack(">BHHBH", 16, 0, 1, 2, 5),
                    struct.pack(">BHHHHBH", 23, 0, 1, 0, 1, 2, 5)):
            assert c.request(pdu) == bytes((pdu[0] | 0x80, 1)), pdu[0]
        with pytest.raises(ModbusExceptionReply):
            c.write_registers(0, [1])
        assert c.read_registers(12, 1)[0] >= 0  # reads still served
    assert d.stop() == 0


def _refused_before_reading(port: int, host: str = "127.0.0.1") -> bool:
    """True if the server closes a new connection without answering a request."""
    try:
        with socket.create_connection((host, port), timeout=5) as s:
            s.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, 0, 1))
            return s.recv(100) == b""
    except (ConnectionResetError, BrokenPipeError):  # the reset may come before connect returns
        return True


def test_allow_list(daemons, tmp_path):
    d = start(daemons, tmp_path, "--allow", "10.0.0.0/8,192.168.1.7", "--log-level", "info")
    assert "clients allowed from: 10.0.0.0/8, 192.168.1.7/32" in "".join(d.out)
    assert _refused_before_reading(d.port)
    assert d.stop() == 0
    assert "not in the allow list" in d.stderr()
    d = start(daemons, tmp_path, "--allow", "10.0.0.0/8", "--allow", "127.0.0.0/8")
    with d.client() as c:
        assert len(c.read_registers(0, 2)) == 2
    assert d.stop() == 0
    err = failed_start(daemons, tmp_path, "--allow", "10.0.0.300")
    assert "not an IP address or network" in err


def _has_ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6) as s:
            s.bind(("::1", 0))
        return True
    except OSError:
        return False


def test_localhost_listens_on_both_loopbacks(daemons, tmp_path):
    d = start(daemons, tmp_path, "--host", "localhost")
    with RawClient("127.0.0.1", d.port, timeout=5) as c:
        c.write_registers(0, [9])
    if not _has_ipv6_loopback():
        d.stop()
        pytest.skip("this machine has no IPv6 loopback (::1): only 127.0.0.1 checked")
    assert f"[::1]:{d.port}" in "".join(d.out)
    with RawClient("::1", d.port, timeout=5) as c:
        assert c.read_registers(0, 1) == [9]
    assert d.stop() == 0


# -- 9, 10: refusals are cheap and not logged one by one -------------------------------------
def test_rate_limited_log_counts_and_summarises(caplog):
    import logging

    from softplc.modbus.server import RateLimitedLog

    now = [0.0]
    rl = RateLimitedLog(logging.getLogger("softplc.test"), 10.0, clock=lambda: now[0])
    with caplog.at_level(logging.WARNING, "softplc.test"):
        for i in range(1000):
            rl.warning("limit", "refusals", "refusing client %d", i)
            rl.warning("header", "bad headers", "bad header from %d", i)
        now[0] = 5.0
        rl.flush()  # interval not over: nothing yet
        assert [r.getMessage() for r in caplog.records] == ["refusing client 0",
                                                            "bad header from 0"]
        now[0] = 10.0
        rl.flush()
        rl.warning("limit", "refusals", "refusing client %d", 1000)
    msgs = [r.getMessage() for r in caplog.records]
    assert msgs[2:] == ["999 more refusals in the last 10 s",
                        "999 more bad headers in the last 10 s", "refusing client 1000"]


def test_storm_is_refused_before_any_protocol_object_or_log(caplog, monkeypatch):
    """Past the client limit a connection is reset straight after accept(): no transport,
    no protocol object, no byte read, one warning per interval."""
    import logging

    from softplc.modbus import ModbusImage, ServerThread
    from softplc.modbus import server as srv
    from softplc.runtime.memory import MemoryImage

    made = [0]
    init = srv._Connection.__init__

    def counting_init(self, server):
        made[0] += 1
        init(self, server)

    monkeypatch.setattr(srv._Connection, "__init__", counting_init)
    th = ServerThread(ModbusImage(MemoryImage()), "127.0.0.1", 0, max_clients=2).start()
    try:
        with caplog.at_level(logging.WARNING, "softplc.modbus"):
            with RawClient("127.0.0.1", th.port) as a, RawClient("127.0.0.1", th.port) as b:
                assert a.read_registers(0, 1) == [0] and b.read_registers(0, 1) == [0]
                refused = 0
                for _ in range(60):
                    if _refused_before_reading(th.port):
                        refused += 1
                assert refused == 60
                assert a.read_registers(0, 1) == [0]  # still served
            until(lambda: th.stats.clients == 0)
            for _ in range(30):  # bad headers: each closes its connection, one warning
                with socket.create_connection(("127.0.0.1", th.port)) as s:
                    s.sendall(b"\x00\x01\x00\x07\x00\x06\x01\x03\x00\x00\x00\x01")
                    assert s.recv(100) == b""
                until(lambda: th.stats.clients == 0)
        assert made[0] == 2 + 30  # the two accepted clients, then the bad-header ones
        assert th.stats.rejected == 60
        warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert len(warnings) == 2 and "2 clients already connected" in warnings[0]
        assert "bad MBAP header" in warnings[1]
    finally:
        th.stop()


def test_front_end_write_path_and_protect():
    """The write path any front-end uses: same checks and codes as Modbus."""
    from softplc.modbus import ModbusImage, ReadOnly
    from softplc.modbus.image import WriteRefused
    from softplc.runtime.memory import MemoryImage

    mem = MemoryImage()
    img = ModbusImage(mem)
    img.protect(ReadOnly(registers=((200, 204),)))
    img.write_words(10, [-1, 7])
    img.write_bits(3, [True])
    with pytest.raises(WriteRefused) as e:
        img.write_words(203, [1])
    assert e.value.code == 2 and "read-only" in str(e.value)
    with pytest.raises(WriteRefused) as e:
        img.write_bits(256, [1])
    assert e.value.code == 2
    assert mem.mw.w[10] == 0 and img.read_registers_wire(10, 2) == b"\xff\xff\x00\x07"
    img.apply_writes()
    assert (mem.mw.w[10], mem.mw.w[11], mem.m[3]) == (-1, 7, 1)
    img.writes_allowed = False
    with pytest.raises(WriteRefused) as e:
        img.write_words(0, [1])
    assert e.value.code == 1


def test_on_serving_hook_gets_the_server_and_the_write_path(tmp_path):
    """In-process: what a second front-end (web monitor) gets, and its writes are kept."""
    import io

    from softplc.daemon import Daemon as InProcessDaemon
    from softplc.daemon import DaemonOptions
    from softplc.plc import PLC

    seen = []

    def hook(server, image):
        image.write_words(5, [42])
        seen.append(server.port)
        daemon.request_stop()

    state = tmp_path / "plc.state"
    opts = DaemonOptions(port=0, state=state, stats_interval=0, rt_priority=0,
                         on_serving=[hook])
    daemon = InProcessDaemon(PLC.from_source(PROGRAM, clock="real"), opts, out=io.StringIO())
    before = signal.getsignal(signal.SIGINT)  # whatever earlier tests left installed
    assert daemon.run() == 0
    assert seen and seen[0] > 0
    assert struct.unpack_from("<h", retain.load(state).mw, 10)[0] == 42
    assert signal.getsignal(signal.SIGINT) is before  # handlers restored after a stop by code
