"""`[daemon] host_wait`: with a virtual clock the daemon runs no scan while the program's
"waiting for the host" bit is 1 and no write is pending (repeatable host-driven runs);
real time and `--no-host-wait` ignore the bit; a bad address is a clear error."""

from __future__ import annotations

import re
import time
import urllib.request

from daemon_util import Daemon, started
from waits import WAIT_S

# %M0: waiting while %MW0 = 0; %MW1 counts scans; a write to %MW0 is consumed at once
PROGRAM = """\
LD    [ %MW0 = 0 ]
ST    %M0
LD    1
[ %MW1 := %MW1 + 1 ]
LD    [ %MW0 <> 0 ]
[ %MW0 := 0 ]
"""
CONFIG = '[daemon]\nhost_wait = "%M0"\n'


def start(daemons, tmp, *args: str, config: str = CONFIG, wait: bool = True,
          web: str = "off") -> Daemon:
    cfg = tmp / "m.toml"
    cfg.write_text(config)
    return started(daemons, tmp, "--config", str(cfg), "--stats-interval", "0", "--web",
                   web, *args, program=PROGRAM, wait=wait)


def scans(d: Daemon) -> int:
    with d.client() as c:
        return c.read_registers(1, 1)[0]


def test_the_virtual_clock_waits_for_the_host(daemons, tmp_path):
    d = start(daemons, tmp_path, "--speed", "max", web="0")
    end = time.monotonic() + WAIT_S
    while scans(d) == 0:  # the banner comes before the first scan
        assert time.monotonic() < end
    time.sleep(0.2)  # thousands of scans at --speed max, if any ran
    assert scans(d) == 1  # one scan set the bit, then none
    with d.client() as c:
        for k in range(1, 4):
            c.write_registers(0, [7])  # each write: one scan consumes it, one sets the bit
            end = time.monotonic() + WAIT_S
            while c.read_registers(1, 1)[0] != 1 + 2 * k:
                assert time.monotonic() < end
            time.sleep(0.05)
            assert c.read_registers(1, 1)[0] == 1 + 2 * k
        # a change queued by the web monitor runs one scan too (within a 0.1 s wait slice)
        web = re.search(r"web monitor on (http://127\.0\.0\.1:\d+)", "".join(d.out))[1]
        req = urllib.request.Request(web + "/api/force", b'{"object": "%M7", "value": 1}',
                                     {"Content-Type": "application/json"})
        urllib.request.urlopen(req, timeout=10).close()
        end = time.monotonic() + WAIT_S
        while c.read_registers(1, 1)[0] != 8:
            assert time.monotonic() < end
        time.sleep(0.2)
        assert c.read_registers(1, 1)[0] == 8
    assert d.stop() == 0


def test_no_host_wait_and_real_time_ignore_the_bit(daemons, tmp_path):
    for args in (("--speed", "max", "--no-host-wait"), ("--period", "2ms")):
        d = start(daemons, tmp_path, *args)
        first = scans(d)
        end = time.monotonic() + WAIT_S
        while scans(d) < first + 20:  # scans go on with nobody writing
            assert time.monotonic() < end
            time.sleep(0.01)
        assert d.stop() == 0


def test_host_wait_must_be_a_memory_bit(tmp_path, capsys):
    from softplc.cli import main

    prog, cfg = tmp_path / "p.il", tmp_path / "m.toml"
    prog.write_text(PROGRAM)
    cfg.write_text('[daemon]\nhost_wait = "%MW3"\n')
    assert main(["run", str(prog), "--config", str(cfg), "--port", "0", "--speed", "max",
                 "--web", "off"]) == 1  # refused before anything is bound or opened
    err = capsys.readouterr().err
    assert "host_wait" in err and "%MW3" in err and "memory bit" in err
