"""The README's first example end to end: its `softplc run` line as a daemon (on free ports)
and its `softplc io` lines operating it, as written; the star contactor then runs."""

from __future__ import annotations

import shlex
import time
from pathlib import Path

from daemon_util import ROOT, started
from docs_util import fenced, page
from waits import WAIT_S

from softplc.cli import main as softplc
from softplc.commands.io import Client

SCANS_BETWEEN_LINES = 2  # each line's change applied before the next line is sent


def wait_scans(client: Client, n: int) -> None:
    start = client.status()["scans"]
    end = time.monotonic() + WAIT_S
    while client.status()["scans"] < start + n:
        assert time.monotonic() < end, "the daemon does not scan"


def test_the_readme_run_and_operate_lines(tmp_path, daemons, capsys):
    readme = page("README.md")
    run = shlex.split(fenced(readme, "**Run** it", "sh"))
    assert run[:2] == ["softplc", "run"]
    args = run[2:]
    args[args.index("--web") + 1] = "0"  # a free port, read from the banner (parallel workers)
    args[args.index("--config") + 1] = str(ROOT / args[args.index("--config") + 1])
    web = started(daemons, tmp_path, *args[1:], program=Path(ROOT / args[0])).web_port()
    client = Client(port=web)
    wait_scans(client, 1)
    for line in fenced(readme, "**Operate** it", "sh").splitlines():
        argv = shlex.split(line.split("#")[0])
        assert argv[:2] == ["softplc", "io"]
        assert softplc(["io", "--port", str(web), *argv[2:]]) == 0, line
        wait_scans(client, SCANS_BETWEEN_LINES)
    shown = capsys.readouterr().out
    assert "KM1_MAIN = 1" in shown and "KM2_STAR = 1" in shown and "KM3_DELTA = 0" in shown
