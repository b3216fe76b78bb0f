"""`softplc run` as a subprocess: real clock, real loopback TCP, real signals."""

from __future__ import annotations

import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
from daemon_util import Daemon, started
from waits import WAIT_S

from softplc.cli import main
from softplc.modbus.rawclient import RawClient

ROOT = Path(__file__).resolve().parents[2]

# %MW12 counts scans; %MW11 follows %MW10; %MW14 records the scan count at which the
# program first saw %MW10 change; %MW15 copies %SW0; %MW30/%MW31 count cold/warm starts.
PROGRAM = """\
LD    1
[ %MW12 := %MW12 + 1 ]
LD    1
[ %MW11 := %MW10 ]
LD    [ %MW10 <> %MW13 ]
[ %MW14 := %MW12 ]
LD    1
[ %MW13 := %MW10 ]
LD    1
[ %MW15 := %SW0 ]
LD    %S0
[ %MW30 := %MW30 + 1 ]
LD    %S1
[ %MW31 := %MW31 + 1 ]
LD    %M7
ST    %Q0.0
END
"""


def start(daemons, tmp, *args, **kw) -> Daemon:
    kw.setdefault("program", PROGRAM)
    return started(daemons, tmp, *args, **kw)


def wait_scans(c: RawClient, n: int, timeout: float = WAIT_S) -> int:
    """Wait until the scan counter %MW12 has moved n times; return it."""
    start_ = c.read_registers(12, 1)[0]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        now = c.read_registers(12, 1)[0]
        if (now - start_) & 0xFFFF >= n:
            return now
        time.sleep(0.005)
    raise AssertionError("the PLC does not scan")


def test_banner_sigint_and_period(daemons, tmp_path):
    d = start(daemons, tmp_path, "--period", "20ms", "--stats-interval", "0.2s")
    banner = "".join(d.out)
    assert "prog.il (8 rungs)" in banner and "period 20 ms" in banner
    assert "cold start" in banner and "%MW0..%MW2999" in banner and "%M0..%M255" in banner
    assert "TWDLCAE40DRF" in banner
    stats = d.wait_for(r"^stats ")
    assert re.search(r"scans=\d+ .*overruns=\d+ .*clients=\d+ req/s=\d+", stats)
    with d.client() as c:
        wait_scans(c, 2)
        assert c.read_registers(15, 1) == [20]  # the program reads %SW0 = the period
        rc = d.stop(signal.SIGINT)
        with pytest.raises((ConnectionError, OSError)):  # clients are closed
            c.read_registers(0, 1)
    assert rc == 0
    assert re.search(r"stopped after \d+ scans, \d+ overruns \(\d+ late starts, \d+ starts "
                     r"skipped\), .*outputs 0", d.wait_for("stopped"))


def test_stats_on_request_name_the_monitor(daemons, tmp_path):
    """No periodic line (--stats-interval 0) to scroll the banner away; SIGUSR1 prints one,
    ending with the web monitor's address."""
    d = start(daemons, tmp_path, "--stats-interval", "0", "--web", "0")
    url = re.search(r"web monitor on (\S+)", "".join(d.out))[1]
    with d.client() as c:
        wait_scans(c, 2)
    assert not any(line.startswith("stats ") for line in d.out)
    d.proc.send_signal(signal.SIGUSR1)
    stats = d.wait_for(r"^stats ")
    assert re.search(r"scans=\d+ .* state=RUN web=" + re.escape(url) + "$", stats.strip())
    assert d.stop() == 0


def test_host_write_seen_at_next_scan_not_earlier(daemons, tmp_path):
    d = start(daemons, tmp_path, "--period", "100ms")
    with d.client() as c:
        wait_scans(c, 1)
        for value in (123, 456):
            before = c.read_registers(10, 5)  # %MW10..%MW14
            c.write_registers(10, [value])
            after = c.read_registers(10, 5)
            if after[2] == before[2]:  # no scan finished since: only the write shows
                assert after == [value, *before[1:]]
            end = time.monotonic() + WAIT_S
            while c.read_registers(11, 1) != [value]:
                assert time.monotonic() < end
                time.sleep(0.005)
            seen_at = c.read_registers(14, 1)[0]
            # The first scan to see the write started after it was acknowledged: the one
            # after the last scan the host saw before writing (or the one after, if a scan
            # was in progress when the write arrived).
            assert before[2] < seen_at <= after[2] + 2
    assert d.stop(signal.SIGTERM) == 0


def test_warm_restart_keeps_data_and_cold_resets(daemons, tmp_path):
    state = tmp_path / "plc.state"
    d = start(daemons, tmp_path, "--state", str(state), "--save-interval", "0")
    with d.client() as c:
        wait_scans(c, 1)  # the cold start's scan ran (it counts itself in %MW30)
        c.write_registers(5, [77, 0xFFFF])
        c.call(struct.pack(">BHH", 5, 7, 0xFF00))  # %M7 := 1
        # Acknowledged writes survive even if the shutdown comes before the next scan.
    assert d.stop(signal.SIGTERM) == 0
    assert state.exists()

    d = start(daemons, tmp_path, "--state", str(state))
    assert "warm start" in "".join(d.out)
    with d.client() as c:
        wait_scans(c, 2)
        assert c.read_registers(5, 2) == [77, 0xFFFF]
        assert c.call(struct.pack(">BHH", 1, 7, 1)) == b"\x01\x01\x01"
        assert c.read_registers(30, 2) == [1, 1]  # one cold start (first run), one warm
    assert d.stop() == 0

    d = start(daemons, tmp_path, "--state", str(state), "--cold")
    assert "cold start" in "".join(d.out)
    with d.client() as c:
        wait_scans(c, 2)
        assert c.read_registers(5, 2) == [0, 0]
        assert c.read_registers(30, 2) == [1, 0]
    assert d.stop() == 0


def test_corrupt_state_file_needs_cold(daemons, tmp_path):
    state = tmp_path / "plc.state"
    d = start(daemons, tmp_path, "--state", str(state), "--save-interval", "0")
    with d.client() as c:
        c.write_registers(5, [42])
    assert d.stop() == 0
    state.write_bytes(state.read_bytes()[:-10])  # truncated
    d = start(daemons, tmp_path, "--state", str(state), wait=False)
    assert d.proc.wait(WAIT_S) == 1
    err = d.stderr()
    assert "truncated" in err and "--cold" in err and "Traceback" not in err
    d = start(daemons, tmp_path, "--state", str(state), "--cold")
    assert "cold start" in "".join(d.out)
    assert d.stop() == 0
    d = start(daemons, tmp_path, "--state", str(state))  # the cold run saved a good file
    assert "warm start" in "".join(d.out)
    assert d.stop() == 0


def test_kill9_keeps_every_acknowledged_write(daemons, tmp_path):
    state = tmp_path / "plc.state"
    d = start(daemons, tmp_path, "--state", str(state), "--save-interval", "10s")
    with d.client() as c:
        c.write_registers(5, [1111])
        wait_scans(c, 2)
        c.write_registers(6, [2222])  # acknowledged, maybe not yet scanned
    d.proc.kill()
    d.proc.wait(WAIT_S)
    d = start(daemons, tmp_path, "--state", str(state))
    assert "warm start" in "".join(d.out)
    with d.client() as c:
        assert c.read_registers(5, 2) == [1111, 2222]
    assert d.stop() == 0


TIMER_PROGRAM = """\
BLK   %TM0
LD    1
IN
OUT_BLK
LD    Q
ST    %M50
END_BLK
LD    1
[ %MW12 := %MW12 + 1 ]
END
"""


def test_speed_max_runs_the_virtual_clock_and_serves(daemons, tmp_path):
    """A 60 s timer finishes within seconds, and Modbus answers meanwhile."""
    cfg = tmp_path / "m.toml"
    cfg.write_text('[timers."%TM0"]\ntype = "TON"\nbase = "1s"\npreset = 60\n')
    d = start(daemons, tmp_path, "--config", str(cfg), "--speed", "max",
              program=TIMER_PROGRAM)
    assert "as fast as possible" in "".join(d.out)
    with d.client() as c:
        end = time.monotonic() + WAIT_S
        while c.call(struct.pack(">BHH", 1, 50, 1)) != b"\x01\x01\x01":  # %TM0.Q -> %M50
            assert time.monotonic() < end, "the virtual clock does not run fast"
            time.sleep(0.01)
        c.write_registers(100, [5])  # writes still go through at full speed
        end = time.monotonic() + WAIT_S
        while c.read_registers(100, 1) != [5]:
            assert time.monotonic() < end
    assert d.stop() == 0


def test_bad_arguments_are_clear_errors(daemons, tmp_path, capsys):
    d = start(daemons, tmp_path, "--period", "1.5ms", wait=False)
    assert d.proc.wait(WAIT_S) == 1
    assert "whole number of ms" in d.stderr()
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen()
    try:
        port = busy.getsockname()[1]
        prog = tmp_path / "p.il"
        prog.write_text(PROGRAM)
        r = subprocess.run([sys.executable, "-m", "softplc", "run", str(prog), "--port",
                            str(port)], capture_output=True, text=True, timeout=15, cwd=ROOT,
                           env=dict(os.environ, PYTHONPATH=str(ROOT)))
        assert r.returncode == 1 and "cannot listen on 127.0.0.1:" in r.stderr
        assert "Traceback" not in r.stderr
    finally:
        busy.close()
    # an argument refused by the parser: in this process (the refused start above is a
    # real `python -m softplc run`, the bad period a forked one)
    with pytest.raises(SystemExit) as refused:
        main(["run", str(tmp_path / "p.il"), "--speed", "-3"])
    assert refused.value.code == 2 and "bad speed" in capsys.readouterr().err
