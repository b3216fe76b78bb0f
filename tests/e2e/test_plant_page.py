"""The plant page of `softplc plant run --web` (issue 35, softplc.web.plantpage): the
controllers, their state, scans, link health and words; read-only, foreign Hosts refused."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

from waits import WAIT_S
from zygote import default_sigint

ROOT = Path(__file__).resolve().parents[2]
PLANT = ROOT / "ladder_programs" / "plant" / "plant.toml"
BOTH_PEERS = 0b11  # the master's %SW111: peers 1 and 2 answer


def _get(url: str, host: str | None = None) -> tuple[int, str]:
    req = urllib.request.Request(url, headers={"Host": host} if host else {})
    try:
        with urllib.request.urlopen(req, timeout=WAIT_S) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


def test_the_plant_page_shows_controllers_links_and_words():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        [sys.executable, "-m", "softplc", "plant", "run", str(PLANT), "--speed", "1",
         "--set", "master:%I0.0=1", "--web", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        preexec_fn=default_sigint)
    try:
        line = proc.stdout.readline()  # type: ignore[union-attr]
        url = re.search(r"plant page: (http://127\.0\.0\.1:\d+/)", line)[1]
        end = time.monotonic() + WAIT_S
        view: dict = {}
        while time.monotonic() < end:
            view = json.loads(_get(url + "api/plant")[1])
            master = view["controllers"][0] if view.get("controllers") else {}
            if master.get("link", {}) and master["link"]["status"] == BOTH_PEERS \
                    and master["scans"] > 0:
                break
            time.sleep(0.1)
        names = [c["name"] for c in view["controllers"]]
        assert names == ["master", "filler", "capper"]
        master, filler = view["controllers"][0], view["controllers"][1]
        assert master["state"] == "RUN" and master["link"]["status"] == BOTH_PEERS
        assert master["words"]["1"]["present"] is True
        # the master's words to peer 1 are the filler's received words (the link moving)
        t0 = view["time"]
        end = time.monotonic() + WAIT_S
        while time.monotonic() < end and (view["time"] == t0 or
                                          filler["words"]["0"]["received"][1] == 0):
            time.sleep(0.1)
            view = json.loads(_get(url + "api/plant")[1])
            master, filler = view["controllers"][0], view["controllers"][1]
        assert view["time"] > t0
        assert filler["words"]["0"]["received"][1] == master["words"]["1"]["sent"][1] > 0
        status, page = _get(url)
        assert status == 200 and "/api/plant" in page
        status, body = _get(url + "api/plant", host="evil.example")
        assert status == 403 and "not allowed" in body
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
