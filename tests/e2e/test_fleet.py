"""`softplc fleet` (issue 35): several controllers, two programs, one process, each on its
own port, answered by real pymodbus clients; bad options refused with the reason."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

from pymodbus.client import ModbusTcpClient
from waits import until_equal

from softplc.cli import main

ROOT = Path(__file__).resolve().parents[2]
PLUS_ONE = "LD 1\n[ %MW1 := %MW0 + 1 ]\n"
TIMES_TWO = "LD 1\n[ %MW1 := %MW0 * 2 ]\n"
COUNT = 4


def _fleet(tmp: Path, *args: str) -> subprocess.Popen[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "softplc", "fleet", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=tmp)


def test_a_fleet_of_two_programs_answers_each_client_on_its_own_port(tmp_path):
    (tmp_path / "a.il").write_text(PLUS_ONE)
    (tmp_path / "b.il").write_text(TIMES_TWO)
    (tmp_path / "b.toml").write_text('scan_period = "20ms"\n')
    proc = _fleet(tmp_path, "a.il", "b.il,b.toml", "--count", str(COUNT), "--base-port", "0",
                  "--rt-priority", "0")
    try:
        ports: dict[str, int] = {}
        for line in proc.stdout:  # type: ignore[union-attr]
            m = re.match(r"\s+(plc\d+) (\S+) on 127\.0\.0\.1:(\d+)$", line)
            if m:
                ports[m[1]] = int(m[3])
                assert m[2] == ("a.il" if int(m[1][3:]) % 2 else "b.il")  # in turn
            if line.startswith("softplc fleet:"):
                break
        assert len(ports) == COUNT and len(set(ports.values())) == COUNT
        clients = [ModbusTcpClient("127.0.0.1", port=p) for p in ports.values()]
        for i, c in enumerate(clients):
            assert c.connect()
            assert not c.write_register(0, 10 + i).isError()
        for i, c in enumerate(clients):
            want = [10 + i, 11 + i if i % 2 == 0 else 2 * (10 + i)]
            assert until_equal(lambda c=c: c.read_holding_registers(0, count=2).registers,
                          want) == want
            c.close()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    stats = re.search(r"fleet stats controllers=4 scans=(\d+) .* requests=(\d+)", out)
    assert stats and int(stats[1]) > 0 and int(stats[2]) >= 2 * COUNT


def test_bad_fleet_options_are_refused_with_the_reason(tmp_path, monkeypatch, capsys):
    """In this process (`softplc.cli.main`, as `python -m softplc` runs it): the refusal is
    the command's, not the interpreter's start; the test above starts the real process."""
    (tmp_path / "a.il").write_text(PLUS_ONE)
    monkeypatch.chdir(tmp_path)
    for args, reason in [
        (("--count", "0"), "a whole number from 1 to 1000"),
        (("--count", "2", "--ports", "5100,5100"), "2 distinct ports"),
        (("--count", "3", "--ports", "5100,5101"), "3 distinct ports"),
        (("--count", "2", "--base-port", "65535"), "go past 65535"),
    ]:
        try:  # an argparse refusal exits (status 2), the command's returns 1
            rc = main(["fleet", "a.il", *args])
        except SystemExit as e:
            rc = e.code
        err = capsys.readouterr().err
        assert rc in (1, 2) and reason in err, (args, err)
