"""The web monitor's JSON/websocket API and `softplc io`, without a browser.

The stack is the daemon's, in process: a PLC scanned by a thread every few ms, the Modbus
server thread, and the web server attached to its event loop by the daemon's hook.
"""

from __future__ import annotations

import asyncio
import json
import re
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from waits import until

from softplc.access import AccessPort
from softplc.cli import main as cli
from softplc.commands.io import Client, IoError, parse_value
from softplc.modbus import ModbusImage, ServerThread, read_only_of
from softplc.modbus.rawclient import RawClient
from softplc.plc import PLC
from softplc.web import WebOptions, attach, is_loopback, web_token

aiohttp = pytest.importorskip("aiohttp")

ROOT = Path(__file__).resolve().parents[2]
STAR = ROOT / "ladder_programs" / "star_delta.il"
TABLE = ROOT / "ladder_programs" / "drawing_table.il"


class Stack:
    """PLC + scan thread + Modbus server + web monitor, as `softplc run` wires them."""

    def __init__(self, program: Path, config: dict | Path | None = None, **web: object):
        self.plc = PLC.from_file(program, config=config)
        self.image = ModbusImage(self.plc.mem, read_only_of(self.plc.settings.modbus.read_only))
        self.plc.before_scan.append(self.image.apply_writes)
        self.plc.after_scan.append(self.image.take_snapshot)
        self.boundaries = 0
        self.plc.after_scan.append(self._count)
        self.modbus = ServerThread(self.image, "127.0.0.1", 0).start()
        daemon = SimpleNamespace(plc=self.plc, program_name=program.name, overruns=0,
                                 late_starts=0, skipped_starts=0, jitter_max=0.0)
        self.web = attach(daemon, self.modbus, AccessPort(self.plc, self.image),
                          WebOptions(port=0, **web))
        self.port = self.web.server.port
        self._stop = False
        self.lock = threading.Lock()  # held: no scan runs
        self.thread = threading.Thread(target=self._scan, daemon=True)
        self.thread.start()

    def _scan(self) -> None:
        while not self._stop:
            with self.lock:
                self.plc.scan()
            time.sleep(0.002)

    def _count(self) -> None:
        self.boundaries += 1

    def scans(self, n: int = 3) -> None:
        """Wait for n more scan boundaries (queued changes are then applied), in STOP too
        (where the scan count stands still)."""
        end = self.boundaries + n
        until(lambda: self.boundaries >= end, period=0.002)

    def client(self, token: str | None = None) -> Client:
        return Client("127.0.0.1", self.port, token)

    def close(self) -> None:
        self._stop = True
        self.thread.join(2)
        self.web.stop()
        self.modbus.stop()


def _release_and_reset(s: Stack, c: Client) -> None:
    """Stop (NC) and overload (NC) closed, fault reset pulsed: ready to start."""
    c.set("%I0.1", 1)
    c.set("%I0.2", 1)
    c.set("%I0.3", 1)
    c.set("%I0.3", 0)
    s.scans(5)


# ---- reads ----------------------------------------------------------------------------------
def test_info_and_status(star):
    c = star.client()
    info = c.request("info")
    assert info["profile"] == "TWDLCAE40DRF"
    assert info["modules"][0] == {"slot": 0, "name": "TWDLCAE40DRF", "inputs": 24,
                                  "outputs": 16}
    assert len(info["rungs"]) == len(star.plc.rungs)
    assert "star contactor" in info["rungs"][4]["title"]
    assert info["token_required"] is False and info["read_only"] is False
    star.scans()  # a loaded machine may not have run a scan yet since the fixture started
    st = c.status()
    assert st["state"] == "RUN" and st["scans"] > 0 and st["period_ms"] == 10
    assert {"scan_last_ms", "scan_min_ms", "scan_max_ms", "overruns", "late_starts",
            "skipped_starts", "modbus_clients"} <= set(st)


def test_read_ranges_blocks_and_bits(star):
    star.plc["%MW20"] = 7
    star.scans()
    v = star.client().get("%MW19:3", "%TM0", "%I0.0:2", "%MF4", "%C0.V")
    assert v["%MW20"] == 7 and v["%MW19"] == 0 and v["%MW21"] == 0
    assert v["%TM0"]["P"] == 50 and v["%TM0"]["type"] == "TON" and v["%TM0"]["base"] == "100ms"
    assert v["%I0.0"] == 0 and "%I0.1" in v
    assert v["%MF4"] == 0.0 and v["%C0.V"] == 0
    star.plc["%MF6"] = float("inf")  # a float word can hold what JSON cannot
    star.scans()
    assert star.client().get("%MF6") == {"%MF6": "inf"}


def test_every_bit_reads_0_or_1_even_one_a_comparison_stored(tmp_path):
    """The compiled comparison stores a Python bool; the API sends 0/1 all the same (an
    output bit sent as `true` once broke the animation table)."""
    il = tmp_path / "compare.il"
    il.write_text("LD [%MW0 > 3]\nST %M5\nLD [%MW0 > 3]\nST %Q0.2\n", encoding="utf-8")
    s = Stack(il)
    try:
        c = s.client()
        c.set("%MW0", 7)
        s.scans()
        assert s.plc.mem.m[5] is True  # what the program stored
        v = c.get("%M5", "%Q0.2", "%Q0.2:2", "%MW0:X0")
        assert v == {"%M5": 1, "%Q0.2": 1, "%Q0.3": 0, "%MW0:X0": 1}
        assert all(type(x) is int for x in v.values())
        io = c.request("io")["io"]
        assert type(io["%Q0.2"]["value"]) is int and io["%Q0.2"]["value"] == 1
    finally:
        s.close()


@pytest.mark.parametrize("obj, message", [
    ("%XX0", "unknown object"), ("%MW5000", "beyond the controller profile"),
    ("MW3", "start with %"), ("%TM99", "not configured"), ("%I0.40", "has 24 inputs"),
])
def test_read_unknown_object(star, obj, message):
    with pytest.raises(IoError, match=message) as e:
        star.client().get(obj)
    assert "HTTP 400" in str(e.value)


# ---- writes -------------------------------------------------------------------------------
def test_write_word_read_back_over_modbus(star):
    c = star.client()
    assert c.set("%MW3", 1234) == ["%MW3"]
    with RawClient("127.0.0.1", star.modbus.port) as m:
        assert m.read_registers(3, 1) == [1234]  # acknowledged: Modbus reads it back at once
    star.scans()
    assert star.plc["%MW3"] == 1234
    c.set("%MF40", 1.5)
    c.set("%MD50", -100000)
    c.request("write", {"writes": [{"object": "%MW60:3", "value": [1, 2, 3]},
                                   {"object": "%M7", "value": 1}]})
    star.scans()
    assert star.plc["%MF40"] == 1.5 and star.plc["%MD50"] == -100000
    assert star.plc["%MW60:3"] == [1, 2, 3] and star.plc["%M7"]


def test_write_applied_at_scan_boundary_push_button_seen(star):
    """A press and its release sent back to back: the program still sees the press."""
    s, c = star, star.client()
    _release_and_reset(s, c)
    assert s.plc["%MW11"] == 0
    with s.lock:  # no scan between the two: both wait in the queue
        c.set("%I0.0", 1)
        c.set("%I0.0", 0)
    s.scans(5)
    assert s.plc["%Q0.0"] and s.plc["%Q0.1"] and not s.plc["%Q0.2"]  # main + star
    assert s.plc["%MW11"] == 1


@pytest.mark.parametrize("obj, value, status, message", [
    ("%ZZ1", 1, 400, "unknown object"),
    ("%MW3", 70000, 400, "out of range"),
    ("%MW3", 1.5, 400, "not whole"),
    ("%MW3", "abc", 400, "not a number"),
    ("%I0.0", 2, 400, "value 0 or 1"),
    ("%MF4", 1e39, 400, "32-bit float"),
    ("%KW0", 1, 403, "constant"),
    ("%TM0.V", 3, 403, "read-only"),
    ("%TM0", 3, 403, "function block"),
    ("%TM0.P", 10000, 400, "out of range 0..9999"),
])
def test_bad_write_is_refused_and_nothing_applied(star, obj, value, status, message):
    star.scans()  # past the first scans (the fault latched, STATE = 9): the words settled
    before = star.plc.mem.snapshot()
    with pytest.raises(IoError, match=message) as e:
        star.client().request("write", {"writes": [{"object": "%MW7", "value": 99},
                                                   {"object": obj, "value": value}]})
    assert f"HTTP {status}" in str(e.value)
    star.scans()
    assert star.plc["%MW7"] == 0  # the good write before the bad one was not applied either
    assert star.plc.mem.snapshot()["mw"] == before["mw"]


def test_modbus_read_only_range_applies_to_the_web_too():
    s = Stack(STAR, {"modbus": {"read_only": ["%MW100:10"]},
                     "timers": {"%TM0": {"base": "100ms", "preset": 50},
                                "%TM1": {"base": "10ms", "preset": 6}}})
    try:
        with pytest.raises(IoError, match="read-only"):
            s.client().set("%MW105", 1)
        s.client().set("%MW99", 1)
        s.scans()
        assert s.plc["%MW99"] == 1 and s.plc["%MW105"] == 0
    finally:
        s.close()


def test_malformed_requests(star):
    c = star.client()
    for path, body, message in [
        ("write", {"value": 1}, 'missing "object"'),
        ("write", {"writes": "x"}, "a list of"),
        ("force", {"object": "%I0.0"}, 'missing "value"'),
        ("control", {"action": "reboot"}, "one of run, stop, cold, warm"),
    ]:
        with pytest.raises(IoError, match=message):
            c.request(path, body)
    with pytest.raises(IoError, match="JSON object"):
        c.request("write", [1, 2])


# ---- forcing, RUN/STOP -----------------------------------------------------------------------
def test_force_and_unforce(star):
    s, c = star, star.client()
    _release_and_reset(s, c)
    assert c.force("%I0.1", 0) == ["%I0.1"]  # stop held pressed
    s.scans()
    assert s.plc.forced == {"%I0.1": 0} and c.status()["forced"] == {"%I0.1": 0}
    c.set("%I0.0", 1)
    c.set("%I0.0", 0)
    s.scans(5)
    assert not s.plc["%Q0.0"]  # the forced stop wins
    with pytest.raises(IoError, match="cannot be forced"):
        c.force("%TM0.P", 1)
    with pytest.raises(IoError, match="value 0 or 1"):
        c.force("%Q0.0", 5)
    assert c.unforce("%I0.1") == ["%I0.1"]
    s.scans()
    assert s.plc.forced == {}
    c.force("%Q0.3", 1)
    c.force("%MW30", 77)
    s.scans()
    assert s.plc["%Q0.3"] and s.plc["%MW30"] == 77
    c.unforce()
    s.scans()
    assert s.plc.forced == {}


def test_run_stop_cold_warm(star):
    s, c = star, star.client()
    c.control("stop")
    s.scans()
    assert s.plc.state == "STOP" and c.status()["state"] == "STOP"
    c.control("run")
    s.scans()
    assert s.plc.state == "RUN"
    c.set("%MW40", 5)
    s.scans()
    c.control("warm")
    s.scans()
    assert s.plc["%MW40"] == 5
    c.control("cold")
    s.scans()
    assert s.plc["%MW40"] == 0 and s.plc.state == "RUN"


# ---- security -------------------------------------------------------------------------------
def test_token_required_for_changes():
    s = Stack(STAR, STAR.with_suffix(".toml"), token="s3cret")
    try:
        assert s.client().request("info")["token_required"] is True
        assert s.client().get("%MW3") == {"%MW3": 0}  # reads need no token
        for tok, msg in ((None, "needs a token"), ("wrong", "wrong token")):
            for call in (lambda c: c.set("%MW3", 9), lambda c: c.force("%I0.0", 1),
                         lambda c: c.control("stop"), lambda c: c.unforce()):
                with pytest.raises(IoError, match=msg) as e:
                    call(s.client(tok))
                assert "HTTP 401" in str(e.value)
        s.scans()
        assert s.plc["%MW3"] == 0 and s.plc.state == "RUN" and s.plc.forced == {}
        s.client("s3cret").set("%MW3", 9)
        s.scans()
        assert s.plc["%MW3"] == 9
        base = ["io", "--port", str(s.port)]
        assert cli(base + ["set", "%MW4", "1"]) == 1  # softplc io: no token
        assert cli(base + ["--token", "s3cret", "set", "%MW4", "2"]) == 0
        s.scans()
        assert s.plc["%MW4"] == 2
    finally:
        s.close()


def test_read_only_monitor():
    s = Stack(STAR, STAR.with_suffix(".toml"), read_only=True)
    try:
        c = s.client()
        assert c.request("info")["read_only"] is True
        for call in (lambda: c.set("%MW3", 1), lambda: c.force("%I0.0", 1),
                     lambda: c.control("stop"), lambda: c.unforce()):
            with pytest.raises(IoError, match="read-only") as e:
                call()
            assert "HTTP 403" in str(e.value)
        assert c.get("%MW3") == {"%MW3": 0}
        assert s.plc.state == "RUN"
    finally:
        s.close()


def test_other_sites_pages_are_refused(star):
    """A page of another origin open in the user's browser cannot write (CSRF) or read."""
    import urllib.error
    import urllib.request

    base = f"http://127.0.0.1:{star.port}/api/"
    cases = [("write", b'{"object": "%MW3", "value": 5}', {"Content-Type": "text/plain"}, 415),
             ("write", b'{"object": "%MW3", "value": 5}',
              {"Content-Type": "application/json", "Origin": "http://evil.example"}, 403),
             ("status", None, {"Origin": "http://evil.example"}, 403)]
    for path, body, headers, status in cases:
        req = urllib.request.Request(base + path, data=body, headers=headers)
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=5)
        assert e.value.code == status
        assert "error" in json.loads(e.value.read())
    same = urllib.request.Request(base + "status",
                                  headers={"Origin": f"http://127.0.0.1:{star.port}"})
    with urllib.request.urlopen(same, timeout=5) as r:
        assert json.loads(r.read())["state"] == "RUN"
    star.scans()
    assert star.plc["%MW3"] == 0


def test_loopback_detection_and_token_policy():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    assert web_token(WebOptions(host="127.0.0.1")) is None
    t1, t2 = web_token(WebOptions(host="0.0.0.0")), web_token(WebOptions(host="0.0.0.0"))
    assert t1 and t2 and t1 != t2 and len(t1) >= 16  # random, printed at start
    # beyond loopback reads need a token too: a read-only monitor gets one as well, unless
    # it has its read-only token
    assert web_token(WebOptions(host="0.0.0.0", read_only=True))
    assert web_token(WebOptions(host="0.0.0.0", read_only=True, read_token="r")) is None
    assert web_token(WebOptions(host="0.0.0.0", token="mine")) == "mine"


# ---- live views -----------------------------------------------------------------------------
def test_io_and_live_ladder(star):
    s, c = star, star.client()
    _release_and_reset(s, c)
    io = c.request("io")
    assert io["io"]["%I0.1"] == {"value": 1, "forced": False, "driven_by": ""}
    assert len(io["io"]) == 24 + 16
    svg_off = _get_text(s, "/api/ladder/4")
    c.set("%I0.0", 1)
    c.set("%I0.0", 0)
    s.scans(5)
    svg_on = _get_text(s, "/api/ladder/4")
    assert svg_on.startswith("<svg") and "%Q0.1" in svg_on
    assert svg_on.count('class="on"') > svg_off.count('class="on"') >= 1  # power flows
    assert {"%I0.0", "%I0.1", "%Q0.0", "%Q0.3"} <= set(c.request("info")["io_used"])
    assert "%I0.7" not in c.request("info")["io_used"]
    with pytest.raises(IoError, match="rungs 0..8"):
        c.request("ladder/99")


def _get_text(s: Stack, path: str) -> str:
    import urllib.request

    with urllib.request.urlopen(f"http://127.0.0.1:{s.port}{path}", timeout=5) as r:
        assert r.headers["Content-Type"].startswith("image/svg+xml")
        return r.read().decode()


def test_machine_view_and_device_driven_inputs():
    s = Stack(TABLE, TABLE.with_suffix(".toml"))
    try:
        c = s.client()
        info = c.request("info")
        assert info["device_io"]["%I0.12"] == "home_X" and info["device_io"]["%Q0.14"] == "pen"
        assert [m["name"] for m in info["modules"]] == ["TWDLCAE40DRF", "TM2DDO8TT"]
        with pytest.raises(IoError, match="driven by the simulated device 'home_X'"):
            c.set("%I0.12", 1)
        m = c.request("machine")
        x = m["devices"]["X"]
        assert x["type"] == "stepper" and x["view"]["travel"] == 25.0
        assert m["trace_total"] >= 1 and len(m["trace"][0]) == 5
        later = c.request(f"machine?since={m['trace_total']}")
        assert later["trace_from"] == m["trace_total"]
        c.force("%I0.12", 1)  # forcing overrides the device
        s.scans()
        assert s.plc["%I0.12"]
    finally:
        s.close()


def test_websocket_updates(star):
    s = star

    async def talk() -> list[dict]:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f"http://127.0.0.1:{s.port}/api/ws") as ws:
                await ws.send_str(json.dumps({"subscribe": {
                    "objects": ["%MW20:2", "%TM0"], "io": True, "rungs": [4, 5]}}))
                got = []
                t0 = time.monotonic()
                while len([m for m in got if m.get("type") == "update"]) < 6:
                    got.append(json.loads((await ws.receive(timeout=5)).data))
                rate = 5 / (time.monotonic() - t0)
                await ws.send_str(json.dumps({"subscribe": {"objects": ["%NOPE"]}}))
                while True:
                    m = json.loads((await ws.receive(timeout=5)).data)
                    if m["type"] == "error":
                        got.append(m)
                        break
                await ws.send_str("not json")
                got.append(json.loads((await ws.receive(timeout=5)).data))
                return got + [{"rate": rate}]

    s.plc["%MW21"] = 5
    got = asyncio.run(talk())
    ups = [m for m in got if m.get("type") == "update"]
    assert ups[-1]["values"]["%MW21"] == 5 and ups[-1]["values"]["%TM0"]["P"] == 50
    assert ups[-1]["io"]["%I0.0"] == 0 and ups[-1]["status"]["state"] == "RUN"
    assert set(ups[0]["ladder"]) == {"4", "5"}  # the first update carries every rung
    assert got[-3]["type"] == "error" and "unknown object '%NOPE'" in got[-3]["error"]
    assert got[-2]["type"] == "error"
    assert got[-1]["rate"] > 4  # about UPDATE_HZ; loose: the machine is shared


# ---- softplc io -----------------------------------------------------------------------------
def test_softplc_io_command(star, capsys):
    s = star
    base = ["io", "--port", str(s.port)]
    assert cli(base + ["set", "%MW3", "16#10", "%MW4", "-2"]) == 0
    s.scans()
    assert cli(base + ["get", "%MW3:2"]) == 0
    assert capsys.readouterr().out.splitlines()[-2:] == ["%MW3 = 16", "%MW4 = -2"]
    # bits as 1/0 and a timer as `softplc repl` prints them (softplc.twido.display), not a dict
    assert cli(base + ["get", "%Q0.0:3", "%TM0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split(" = ")[1] in ("0", "1") for ln in lines[:3]] == [True] * 3
    assert re.fullmatch(r"%TM0 STAR_TIME = TON base 100ms Q=[01] V=\d+ P=50", lines[3]), \
        lines[3]
    # symbols (star_delta.toml's symbols_file) name objects for the API too
    assert cli(base + ["set", "FAULT_RESET", "1"]) == 0
    s.scans()
    assert cli(base + ["get", "fault_reset", "STAR_TIME.P"]) == 0
    assert capsys.readouterr().out.splitlines()[-2:] == ["%I0.3 FAULT_RESET = 1",
                                                          "%TM0.P STAR_TIME.P = 50"]
    # a range by symbol, and an address shown with its symbol (issue 33)
    assert cli(base + ["get", "STARTS:2", "%Q0.0", "%MW12"]) == 0
    lines = capsys.readouterr().out.splitlines()[-4:]
    assert [ln.split(" = ")[0] for ln in lines] == [
        "%MW10 STARTS", "%MW11 STATE", "%Q0.0 KM1_MAIN", "%MW12"], lines
    assert all(re.fullmatch(r"-?\d+", ln.split(" = ")[1]) for ln in lines), lines
    assert cli(base + ["set", "FAULT_RESET", "0"]) == 0
    assert cli(base + ["get", "STRATS"]) == 1
    assert "unknown symbol 'STRATS' (did you mean STARTS?)" in capsys.readouterr().err
    assert cli(base + ["force", "%I0.1", "0"]) == 0
    s.scans()
    assert s.plc.forced == {"%I0.1": 0}
    assert cli(base + ["unforce"]) == 0
    assert cli(base + ["stop"]) == 0
    s.scans()
    assert s.plc.state == "STOP"
    assert cli(base + ["run"]) == 0
    assert cli(base + ["--json", "status"]) == 0
    out = capsys.readouterr().out
    assert json.loads(out[out.index("{"):])["state"] in ("RUN", "STOP")
    assert cli(base + ["set", "%KW0", "1"]) == 1
    assert "constant" in capsys.readouterr().err
    assert cli(base + ["set", "%MW3"]) == 1
    assert "OBJECT VALUE pairs" in capsys.readouterr().err


def test_softplc_io_without_daemon(capsys):
    from modbus_util import refused_port

    with refused_port() as port:  # nobody listens there, and no parallel worker takes it
        assert cli(["io", "--port", str(port), "status"]) == 1
    assert "no softplc web API" in capsys.readouterr().err


def test_parse_value():
    assert parse_value("16#FF") == 255 and parse_value("2#1010") == 10
    assert parse_value("-5") == -5 and parse_value("1.5") == 1.5 and parse_value("0x10") == 16
    with pytest.raises(IoError, match="not a number"):
        parse_value("abc")


def test_web_benchmark_pages(star):
    """tools/bench_web.py's page load generator: N websocket pages, their update rates."""
    import multiprocessing as mp
    import sys

    sys.path.insert(0, str(ROOT / "tools"))
    import bench_web

    q = mp.get_context("fork").Queue()
    bench_web._pages(star.port, 2, time.time() + 0.2, 0.6, q)
    rates = q.get(timeout=5)
    assert len(rates) == 2 and all(r > 0 for r in rates)


def test_port_taken_default_falls_back_explicit_fails():
    import socket

    from softplc.errors import SoftPLCError

    plc = PLC.from_file(STAR, config=STAR.with_suffix(".toml"))
    image = ModbusImage(plc.mem)
    modbus = ServerThread(image, "127.0.0.1", 0).start()
    daemon = SimpleNamespace(plc=plc, program_name="x", overruns=0, late_starts=0,
                             skipped_starts=0, jitter_max=0.0)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        try:
            with pytest.raises(SoftPLCError, match=f"cannot listen on 127.0.0.1:{port}"):
                attach(daemon, modbus, AccessPort(plc, image),
                       WebOptions(port=port, port_given=True))
            web = attach(daemon, modbus, AccessPort(plc, image),
                         WebOptions(port=port, port_given=False))
            assert web.server.port != port
            assert f"(port {port} is taken)" in web.banner()[0]
            web.stop()
        finally:
            modbus.stop()


def test_run_command_web_options(tmp_path):
    import sys

    sys.path.insert(0, str(ROOT / "tests"))
    from daemon_util import Daemon

    d = Daemon(tmp_path, "--config", str(STAR.with_suffix(".toml")), "--web", "0",
               "--web-read-only", "--stats-interval", "0", program=STAR)
    try:
        line = next(x for x in d.out if "web monitor on" in x)
        assert line.rstrip().endswith("(read-only)")
        port = d.web_port()
        assert Client("127.0.0.1", port).request("info")["read_only"] is True
    finally:
        assert d.stop() == 0
    d = Daemon(tmp_path, "--config", str(STAR.with_suffix(".toml")), "--web", "off",
               "--stats-interval", "0", program=STAR)
    try:
        assert not any("web monitor" in x for x in d.out)
    finally:
        assert d.stop() == 0


def test_fast_reader_agrees_with_memory_read():
    """The scan-thread reader gives what `MemoryImage.read` gives, latched or not."""
    plc = PLC.from_file(TABLE, config=TABLE.with_suffix(".toml"))
    ctl = AccessPort(plc)
    plc.run(0.05)
    plc["%MW5"], plc["%MD8"], plc["%MF20"], plc["%M3"], plc["%SW40"] = 7, -70000, 2.5, 1, 9
    plc.mem.i_field[20] = 1  # %I0.20: never latched, read from the field
    objs = ["%MW0:12", "%MD8", "%MF20", "%M0:5", "%S4:4", "%SW40", "%Q0.14", "%Q1.0:8",
            "%I0.0:24", "%TM0", "%TM1.P", "%MW5:X0", "%MW0[%MW5]", "%X0", "%KW0"]
    refs = ctl.objects.resolve_many(objs)
    assert ctl.reading.values_fn(refs)() == {n: ctl.reading.read_one(r) for n, r in refs}
    assert ctl.reading.values_fn(refs)()["%I0.20"] == 1
    plc.force("%I0.20", 0)  # now latched and forced: the reader is rebuilt
    plc.scan()
    assert ctl.reading.values_fn(refs)()["%I0.20"] == 0 == plc["%I0.20"]


# ---- analog channels --------------------------------------------------------------------------
THERMO = ROOT / "ladder_programs" / "analog_thermostat.il"


@pytest.fixture(scope="module")
def thermo():
    s = Stack(THERMO, THERMO.with_suffix(".toml"))
    yield s
    s.close()


def test_analog_channels_listed_with_span_and_device(thermo):
    chans = {ch["address"]: ch for ch in thermo.client().request("info")["analog"]}
    assert chans["%IW0.0"] == {"address": "%IW0.0", "input": True, "signal": "pot",
                               "range": "normal", "unit": "", "min": 0.0, "max": 1.0,
                               "word_min": 0, "word_max": 1023, "driven_by": "",
                               "configured": True}
    pt = chans["%IW2.0"]
    assert (pt["signal"], pt["unit"], pt["min"], pt["max"]) == ("PT100", "°C", -200, 600)
    assert (pt["word_min"], pt["word_max"], pt["driven_by"]) == (-2000, 6000, "oven")
    assert not chans["%QW2.0"]["input"] and chans["%QW2.0"]["unit"] == "V"
    assert pt["configured"] and not chans["%IW2.1"]["configured"]  # not in [analog]


def test_unconfigured_analog_channel_has_a_word_but_no_value(thermo):
    """The module's second input is not in [analog]: its signal type is unknown, so word 0
    is not shown as -200 °C (PT100's bottom, which reads like a sensor fault)."""
    io = thermo.client().request("io")["analog"]
    assert (io["%IW2.1"]["word"], io["%IW2.1"]["value"]) == (0, None)
    assert io["%IW2.0"]["value"] is not None


def test_analog_input_written_at_scan_boundary(thermo):
    c = thermo.client()
    reply = c.request("analog", {"object": "%IW0.0", "value": 0.5})
    assert reply == {"queued": "%IW0.0", "value": 0.5, "word": 512, "forced": False}
    thermo.scans()
    assert thermo.plc["%IW0.0"] == 512 and thermo.plc["%MW0"] == 128  # the program's copy
    io = c.request("io")["analog"]
    assert io["%IW0.0"]["word"] == 512 and io["%IW0.0"]["value"] == pytest.approx(0.5, abs=1e-3)
    heater = io["%QW2.0"]  # an output: its word and the signal it gives
    assert heater["value"] == pytest.approx(heater["word"] * 10 / 4095, abs=1e-3)


@pytest.mark.parametrize("obj, value, status, message", [
    ("%IW0.0", 1.5, 400, r"out of range 0\.\.1 \(pot\)"),
    ("%IW0.0", "abc", 400, "expected a number"),
    ("%IW0.0", True, 400, "expected a number"),
    ("%IW1.0", 0.2, 400, "not a configured analog channel|unknown object"),
    ("%MW0", 1, 400, "not a configured analog channel"),
    ("%QW2.0", 5.0, 403, "analog output"),
    ("%IW2.0", 25.0, 403, "driven by the simulated device 'oven'"),
])
def test_bad_analog_write_refused_nothing_applied(thermo, obj, value, status, message):
    before = thermo.plc["%IW0.0"]
    with pytest.raises(IoError, match=message) as e:
        thermo.client().request("analog", {"object": obj, "value": value})
    assert f"HTTP {status}" in str(e.value)
    assert thermo.client().request("status")["pending"] == 0
    thermo.scans()
    assert thermo.plc["%IW0.0"] == before  # the pot (no device) unchanged


def test_device_driven_analog_input_forced_then_released(thermo):
    c = thermo.client()
    assert c.request("analog", {"object": "%IW2.0", "value": 500.0, "force": True})["word"] \
        == 5000
    thermo.scans(5)
    assert thermo.plc.forced["%IW2.0"] == 5000
    assert thermo.plc["%QW2.0"] == 0  # the program sees 500 degrees, not the oven: heater off
    assert c.request("io")["analog"]["%IW2.0"]["word"] == 5000
    with pytest.raises(IoError, match="forced: unforce it first"):
        c.request("analog", {"object": "%IW2.0", "value": 20.0})
    c.request("unforce", {"object": "%IW2.0"})
    thermo.scans(5)
    assert "%IW2.0" not in thermo.plc.forced and thermo.plc["%IW2.0"] < 5000  # the oven again


def test_servo_i_variables_tuned_live_from_the_monitor():
    """Issue 23: the animation table edits a running axis's I-variables through its word
    table (%MF328 = Ixx30 of X, word table at %MW300): applied at a servo tick, counted in
    %MW301, read back as the value in force; a value out of range is refused when written
    and the value in force stays."""
    servo = ROOT / "ladder_programs" / "servo_table.il"
    s = Stack(servo, servo.with_suffix(".toml"))
    try:
        c = s.client()
        axis = s.plc.devices["X"]
        kp = axis.gains.kp
        c.set("%MF328", kp * 2)
        s.scans(5)
        assert axis.gains.kp == kp * 2
        got = c.get("%MF328", "%MW300", "%MW301")
        assert got["%MF328"] == kp * 2 and got["%MW300"] == 0 and got["%MW301"] >= 1
        # Ixx30 >= 0, and within its PMAC range (issue 31): refused when written, with the
        # axis's reason (issue 33), never queued; the value in force stays
        for bad in (-1.0, 1e30, 3.4e38):
            with pytest.raises(IoError, match=r"%MF328 := \S+ refused: device 'X': Ixx30"):
                c.set("%MF328", bad)
            s.scans(5)
            got = c.get("%MF328", "%MW300")
            assert axis.gains.kp == kp * 2 and got["%MF328"] == kp * 2 and got["%MW300"] == 0
    finally:
        s.close()


# ---- symbols (issue 33) -----------------------------------------------------------------------
def test_resolve_and_the_objects_each_rung_uses(star):
    """GET /api/resolve: the address a typed text names, by the daemon's symbol table; the
    rungs of /api/info list the objects they use (the ladder's find box matches their
    symbols)."""
    c = star.client()
    for text, address in (("starts:2", "%MW10:2"), ("STAR_TIME.p", "%TM0.P"),
                          ("%mw3", "%MW3"), ("STATE:X3", "%MW11:X3")):
        assert c.request("resolve?obj=" + text) == {"address": address}, text
    for text, message in (("STRATS", "unknown symbol 'STRATS' (did you mean STARTS?)"),
                          ("%TM9", "%TM9 is not configured")):
        with pytest.raises(IoError, match=re.escape(message) + r".*\(HTTP 400\)"):
            c.request("resolve?obj=" + text)
    rungs = c.request("info")["rungs"]
    uses_m10 = [r["index"] for r in rungs if "%M10" in r["uses"]]
    assert uses_m10 and all("%M10" in r["il"] for r in rungs if r["index"] in uses_m10)
    timer = next(r for r in rungs if "%TM0.Q" in r["uses"] or "%TM0" in r["uses"])
    assert "%TM0" in timer["uses"]  # the block beside its field
    # a new program: its rungs' uses, not the listed ones of the old program
    from softplc.il.parser import parse
    with star.lock:
        star.plc.replace_program(parse("(*RUNG: only*)\nLD %I0.5\nST %M77\n"))
    assert [r["uses"] for r in c.request("info")["rungs"]] == [["%I0.5", "%M77"]]
