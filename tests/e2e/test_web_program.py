"""Online program change over the web API (`POST /api/program`), the program listing and
the Modbus map routes, and `softplc load` (issue 24), on the daemon's stack in process."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from daemon_util import Daemon, started
from test_web_api import STAR, Stack
from waits import WAIT_S, until

from softplc.cli import main as cli
from softplc.commands.io import Client, IoError

SOURCE = STAR.read_text()
# the fault lamp steady instead of blinking: no block changes, nothing lost
STEADY = SOURCE.replace("LD    %M1\nAND   %S6\nST    %Q0.3", "LD    %M1\nST    %Q0.3")
# the starts counter removed: its value is lost, a confirmation is needed
NO_COUNTER = SOURCE.replace("BLK   %C0\nLD    %Q0.0\nCU\nEND_BLK\n", "").replace(
    "[ %MW10 := %C0.V ]", "[ %MW10 := 0 ]")
CONFIG = STAR.with_suffix(".toml").read_text()
NO_COUNTER_CONFIG = CONFIG.replace('[counters."%C0"]\npreset = 9999\n', "")


def counted(s: Stack, n: int) -> None:
    """%C0 (starts) set to n through the API, as if the motor had started n times."""
    s.client().set("%C0.P", 9999)
    with s.lock:
        s.plc.mem.blocks["C"][0].set_state(s.plc.mem.blocks["C"][0].state() | {"V": n})
    s.scans()


def test_a_change_without_losses_is_applied_at_once_and_keeps_the_counter(star):
    counted(star, 7)
    c = star.client()
    before = c.request("program")
    assert before["info"]["version"] == 0 and before["source"] == SOURCE
    assert before["rungs"][0]["first_line"] > 0
    answer = c.request("program", {"program": STEADY, "file": "steady.il"})
    assert answer["applied"] is True and answer["losses"] == []
    assert answer["info"]["version"] == 1 and answer["info"]["file"] == "steady.il"
    assert answer["info"]["hash"] != before["info"]["hash"]
    star.scans()
    assert c.get("%C0.V", "%MW10") == {"%C0.V": 7, "%MW10": 7}
    after = c.request("program")
    assert after["source"] == STEADY and after["info"]["version"] == 1
    info = c.request("info")
    assert info["version"]["version"] == 1
    assert info["symbols"]["%MW10"] == ["STARTS", "number of starts"]


def test_errors_are_listed_with_line_and_column_and_nothing_changes(star):
    bad = SOURCE.replace("ST    %Q0.1", "STT   %Q0.1").replace("ST    %Q0.2", "ST    %Q9.9")
    with pytest.raises(IoError, match=r"nothing changed") as e:
        star.client().request("program", {"program": bad})
    assert "(HTTP 400)" in str(e.value)
    req = urllib.request.Request(f"http://127.0.0.1:{star.port}/api/program",
                                 json.dumps({"program": bad}).encode(),
                                 {"Content-Type": "application/json"})
    try:
        urllib.request.urlopen(req, timeout=WAIT_S)
    except urllib.error.HTTPError as err:
        body = json.loads(err.read())
    lines = {(d["line"], d["column"]) for d in body["errors"]}
    assert len(body["errors"]) >= 2 and all(line > 0 and col > 0 for line, col in lines)
    bad_lines = [n for n, text in enumerate(bad.splitlines(), 1) if "STT" in text or "%Q9.9"
                 in text]
    assert sorted(line for line, _ in lines)[:2] == bad_lines
    assert star.plc.program_version == 0 and star.plc.ast.source == SOURCE


def test_losses_need_a_confirmation_then_the_rest_is_kept(star):
    counted(star, 3)
    c = star.client()
    c.set("%MW20", 42)
    change = {"program": NO_COUNTER, "config": NO_COUNTER_CONFIG}
    answer = c.request("program", change)
    assert answer["applied"] is False and answer["needs_confirmation"] is True
    assert answer["losses"] == ["%C0 is no longer used: its value is dropped"]
    assert star.plc.program_version == 0
    answer = c.request("program", change | {"confirm": True})
    assert answer["applied"] is True and answer["info"]["version"] == 1
    star.scans()
    assert c.get("%MW20") == {"%MW20": 42}  # memory kept
    with pytest.raises(IoError, match="not configured or used"):  # the cache was dropped
        c.get("%C0.V")


def test_bad_requests_and_a_restart_section_are_refused(star):
    c = star.client()
    for body, message in (({"program": ""}, '"program"'), ({"program": "LD 1", "cold": 1},
                                                          '"cold": true or false'),
                          ({"program": SOURCE, "config": "scan_period = "}, "configuration"),
                          ({"program": SOURCE, "config": CONFIG.replace("10ms", "20ms", 1)},
                           "cannot change while the PLC runs")):
        with pytest.raises(IoError, match=message):
            c.request("program", body)
    assert star.plc.program_version == 0
    big = {"program": "x" * (5 * 1024 * 1024)}
    with pytest.raises(IoError, match="over 4096 KiB"):
        c.request("program", big)
    with pytest.raises(IoError, match="over 64 KiB"):  # other routes keep their bound
        c.request("write", {"object": "%MW0", "value": 1, "pad": "x" * 70_000})


def test_a_new_configuration_as_text_changes_a_preset(star):
    config = CONFIG.replace("preset = 50", "preset = 20")
    c = star.client()
    answer = c.request("program", {"program": SOURCE, "config": config})
    assert answer["applied"] is False
    assert answer["losses"][0].startswith("%TM0 configuration changed")
    answer = c.request("program", {"program": SOURCE, "config": config, "cold": True})
    assert answer["applied"] and answer["cold"]
    assert c.get("%TM0.P") == {"%TM0.P": 20}
    assert c.get("STAR_TIME.P") == {"%TM0.P": 20}  # the symbols file is still found


def test_read_only_monitor_refuses_a_change():
    s = Stack(STAR, STAR.with_suffix(".toml"), read_only=True)
    try:
        with pytest.raises(IoError, match=r"read-only.*HTTP 403"):
            s.client().request("program", {"program": SOURCE})
    finally:
        s.close()


def test_token_is_needed_for_a_change():
    s = Stack(STAR, STAR.with_suffix(".toml"), token="secret")
    try:
        with pytest.raises(IoError, match="HTTP 401"):
            s.client().request("program", {"program": STEADY})
        assert s.client("secret").request("program", {"program": STEADY})["applied"]
    finally:
        s.close()


def test_map_json_and_csv(star):
    m = star.client().request("map")
    tag = next(t for t in m["tags"] if t["address"] == "%MW10")
    assert (tag["symbol"], tag["comment"], tag["table"]) == ("STARTS", "number of starts",
                                                             "holding register")
    assert tag["start"] == 10 and tag["reference"] == 40011 and 3 in tag["read_fc"]
    hidden = {h["address"]: h for h in m["hidden"]}
    assert hidden["%Q0.1"]["symbol"] == "KM2_STAR" and "%M" in hidden["%Q0.1"]["why"]
    assert "%TM0" in hidden and "not on the map" in m["note"]
    with urllib.request.urlopen(f"http://127.0.0.1:{star.port}/api/map?format=csv",
                                timeout=WAIT_S) as r:
        assert r.headers["Content-Type"].startswith("text/csv")
        assert "attachment" in r.headers["Content-Disposition"]
        rows = r.read().decode().splitlines()
    assert rows[0].startswith("tag,address,type") and any(
        x.startswith("STARTS,%MW10,INT16,holding register,10,40011") for x in rows)
    with pytest.raises(IoError, match="json or csv"):
        star.client().request("map?format=xml")


def test_load_command(star, tmp_path, capsys, monkeypatch):
    counted(star, 5)
    prog = tmp_path / "no_counter.il"
    prog.write_text(NO_COUNTER)
    (tmp_path / "no_counter.toml").write_text(NO_COUNTER_CONFIG)
    port = ["--port", str(star.port), "--config", str(tmp_path / "no_counter.toml")]
    monkeypatch.setattr("builtins.input", lambda prompt="": "n")
    assert cli(["load", str(prog), *port]) == 1  # losses listed, the answer is no
    out = capsys.readouterr()
    assert "%C0 is no longer used" in out.out and "not loaded" in out.err
    assert star.plc.program_version == 0
    assert cli(["load", str(prog), *port, "--yes"]) == 0
    assert "loaded" in capsys.readouterr().out and star.plc.program_version == 1
    bad = tmp_path / "bad.il"
    bad.write_text("LD %I0.0\nSTT %Q0.0\n")
    assert cli(["load", str(bad), *port]) == 1
    err = capsys.readouterr().err
    assert "bad.il:2:1" in err and "Traceback" not in err
    assert cli(["load", str(tmp_path / "none.il"), *port]) == 1
    assert "none.il" in capsys.readouterr().err


def test_symbols_follow_the_new_configuration(star):
    config = CONFIG + '\n[symbols]\nSPEED = { address = "%MW20", comment = "belt speed" }\n'
    c = star.client()
    with pytest.raises(IoError, match="unknown object"):
        c.get("SPEED")
    assert c.request("program", {"program": SOURCE, "config": config})["applied"]
    c.set("speed", 15)
    star.scans()
    assert c.get("SPEED") == {"%MW20": 15}
    assert c.request("info")["symbols"]["%MW20"] == ["SPEED", "belt speed"]
    assert c.request("info")["symbols"]["%MW10"][0] == "STARTS"  # the file's still there


def test_load_into_a_running_daemon(tmp_path, capsys, daemons):
    """`softplc load` against a real `softplc run`: the counter counted by the old program
    survives the change, and the new program runs."""
    d = started(daemons, tmp_path, "--config", str(STAR.with_suffix(".toml")), "--web", "0",
                "--stats-interval", "0", program=STAR)
    port = str(d.web_port())
    c = Client("127.0.0.1", int(port))
    c.set("%I0.1", 1)  # stop (NC) and overload relay (NC) closed, fault reset pulsed
    c.set("%I0.2", 1)
    c.set("%I0.3", 1)
    c.set("%I0.3", 0)
    c.set("%I0.0", 1)  # start: KM1 latches, %C0 counts one start
    until(lambda: c.get("%C0.V")["%C0.V"] == 1)
    prog = tmp_path / "steady.il"
    prog.write_text(STEADY.replace("[ %MW11 := 0 ]", "[ %MW11 := 0 ]\n[ %MW12 := 77 ]"))
    assert cli(["load", str(prog), "--port", port]) == 0
    assert "version 1" in capsys.readouterr().out
    until(lambda: c.get("%MW12")["%MW12"] == 77)
    assert c.get("%C0.V", "%MW12", "%Q0.0") == {"%C0.V": 1, "%MW12": 77, "%Q0.0": 1}


def test_the_state_file_follows_the_loaded_program(tmp_path, capsys, daemons):
    """After `softplc load`, the --state file belongs to the new program: a restart with
    the new program file warm-starts (the counter kept); one with the old file then stops
    and asks (issue 31: never a silent cold start), the old file being no longer the
    command line the running program came from."""
    cfg, state = str(STAR.with_suffix(".toml")), str(tmp_path / "plc.state")
    (tmp_path / "star_delta_symbols.csv").write_bytes(
        (STAR.parent / "star_delta_symbols.csv").read_bytes())
    old = tmp_path / "old.il"
    old.write_text(STAR.read_text())
    new = tmp_path / "steady.il"
    new.write_text(STEADY)

    def start(program: Path) -> tuple[Daemon, str]:
        d = started(daemons, tmp_path, "--config", cfg, "--state", state, "--web", "0",
                    "--stats-interval", "0", program=program)
        return d, str(d.web_port())

    d, port = start(old)
    c = Client("127.0.0.1", int(port))
    c.set("%MW100", 123)  # a retained word no program writes
    until(lambda: c.get("%MW100")["%MW100"] == 123)
    assert cli(["load", str(new), "--port", port, "--yes"]) == 0
    assert d.stop() == 0
    d, port = start(new)
    assert "warm start" in d.out[0], d.out[0]
    assert Client("127.0.0.1", int(port)).get("%MW100")["%MW100"] == 123
    assert d.stop() == 0
    d = started(daemons, tmp_path, "--config", cfg, "--state", state, "--web", "0",
                program=old, wait=False)
    assert d.proc.wait(WAIT_S) == 1
    err = d.stderr()
    assert "steady.il (started" in err and "--program-from-state" in err, err
