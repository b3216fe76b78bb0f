"""Issue 31, online change over the web API on the daemon's stack in one process:
item 1 (POST /api/program names no file of the host; a FIFO does not wedge it) and "an
online change's answer says what happened" (a swap slower than the answer's deadline)."""

from __future__ import annotations

import json
import os
import threading
import time
import urllib.request

import pytest
from test_web_api import STAR
from waits import WAIT_S, until

from softplc.access.program import ProgramAccess
from softplc.commands.io import IoError
from softplc.web import program as web_program

SOURCE = STAR.read_text()
CONFIG = STAR.with_suffix(".toml").read_text()
CHANGED = SOURCE.replace("[ %MW10 := %C0.V ]", "[ %MW10 := %C0.V ]\n[ %MW13 := 31 ]")


def post(port: int, body: dict) -> tuple[int, dict]:
    req = urllib.request.Request(f"http://127.0.0.1:{port}/api/program",
                                 json.dumps(body).encode(),
                                 {"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def naming(path: str) -> str:
    return CONFIG.replace('symbols_file = "star_delta_symbols.csv"', f'symbols_file = "{path}"')


def test_a_page_reaches_no_file_and_a_fifo_wedges_nothing(star, tmp_path):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    for path in ("/etc/passwd", "/dev/zero", str(fifo), "../../etc/passwd"):
        status, body = post(star.port, {"program": SOURCE, "config": naming(path)})
        assert status == 400, body
        assert "names no file of the host" in body["error"] and "root:" not in body["error"]
        assert body["applied"] is False
    # the next change goes through at once (the round-3 FIFO made every later load 409)
    status, body = post(star.port, {"program": CHANGED})
    assert status == 200 and body["applied"] is True and body["info"]["version"] == 1
    status, body = post(star.port, {"program": SOURCE, "config": naming("mine.csv"),
                                    "files": {"mine.csv": "%MW20,SPEED,belt\n"}})
    assert status == 200 and body["applied"] is True
    assert star.client().request("info")["symbols"]["%MW20"] == ["SPEED", "belt"]


def test_bad_files_fields_are_400(star):
    for files, what in (([1], "expected a table"), ({"a": 1}, "expected a table"),
                        ({str(i): "" for i in range(17)}, "at most 16")):
        status, body = post(star.port, {"program": SOURCE, "files": files})
        assert status == 400 and what in body["error"], body
    assert star.plc.program_version == 0


@pytest.fixture
def slow_swap(monkeypatch):
    """The swap takes `delay[0]` seconds in the scan thread; the answer's deadline is
    0.3 s (a swap outliving it: a huge program on a slow machine, a long scan)."""
    delay = [0.0]
    real = ProgramAccess.swap

    def swap(self, *args, **kw):
        time.sleep(delay[0])
        return real(self, *args, **kw)

    monkeypatch.setattr(ProgramAccess, "swap", swap)
    monkeypatch.setattr(web_program, "APPLY_TIMEOUT", 0.3)
    return delay


def test_a_swap_begun_before_the_deadline_is_reported_as_it_ended(star, slow_swap):
    slow_swap[0] = 0.45  # past the first deadline, within the second
    status, body = post(star.port, {"program": CHANGED})
    assert status == 200 and body["applied"] is True, body
    assert star.plc.program_version == 1 and body["info"]["version"] == 1


def test_a_swap_longer_than_both_deadlines_is_reported_pending(star, slow_swap, capsys):
    slow_swap[0] = 1.0
    status, body = post(star.port, {"program": CHANGED})
    assert status == 202 and body["applied"] is None and body["version"] == 1, body
    until(lambda: star.plc.program_version == 1)
    assert star.client().request("program")["info"]["version"] == 1


def test_a_swap_not_begun_at_the_deadline_never_applies(star, slow_swap):
    """The scan thread held (no scan boundary) past the deadline: "not changed", and it
    stays true once the scans go on."""
    held, answered = threading.Event(), threading.Event()

    def hold() -> None:  # until the answer came, however long planning took (a loaded
        with star.lock:  # machine: a fixed 0.8 s hold once ended before the swap was queued)
            held.set()
            answered.wait(WAIT_S)

    t = threading.Thread(target=hold)
    t.start()
    held.wait()
    try:
        with pytest.raises(IoError, match=r"not changed \(HTTP 503\)"):
            star.client().request("program", {"program": CHANGED})
    finally:
        answered.set()
        t.join()
    star.scans(10)
    assert star.plc.program_version == 0 and star.plc.ast.source == SOURCE


def test_softplc_load_sends_the_files_its_configuration_names(star, tmp_path):
    from softplc.cli import main as cli

    (tmp_path / "mine.csv").write_bytes("%MW20;VITESSE;vitesse du tapis é\n".encode("cp1252"))
    cfg = tmp_path / "new.toml"
    cfg.write_text(naming("mine.csv"))
    prog = tmp_path / "p.il"
    prog.write_text(SOURCE)
    assert cli(["load", str(prog), "--port", str(star.port), "--config", str(cfg)]) == 0
    assert star.client().request("info")["symbols"]["%MW20"] == ["VITESSE",
                                                                 "vitesse du tapis é"]
