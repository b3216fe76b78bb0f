"""The web monitor under attack (issue 21): DNS rebinding, tokens beyond loopback, huge
subscriptions, too many or stalled pages, a flooded change queue, malformed bodies.

Each test runs the daemon's stack in process on 127.0.0.1 (test_web_api.Stack) and is
bounded in time: a refusal must come at once, not after the damage.
"""

from __future__ import annotations

import asyncio
import json
import logging

import pytest
from test_web_api import ROOT, STAR, Stack
from waits import WAIT_S, until

from softplc.access import commands, objects
from softplc.web import pages

aiohttp = pytest.importorskip("aiohttp")


async def _http(port: int, method: str, path: str, body: bytes | None = None,
                headers: dict[str, str] | None = None) -> tuple[int, str, dict[str, str]]:
    hdrs = {"Content-Type": "application/json"} if body is not None else {}
    hdrs.update(headers or {})
    async with aiohttp.ClientSession() as session:
        async with session.request(method, f"http://127.0.0.1:{port}{path}", data=body,
                                   headers=hdrs) as r:
            return r.status, await r.text(), {k: m.value for k, m in r.cookies.items()}


def http(port: int, method: str, path: str, body: bytes | None = None,
         headers: dict[str, str] | None = None) -> tuple[int, str]:
    status, text, _ = asyncio.run(_http(port, method, path, body, headers))
    return status, text


async def _ws_status(port: int, headers: dict[str, str] | None = None) -> int:
    """101 if the websocket upgrade succeeds, else the HTTP status of the refusal."""
    async with aiohttp.ClientSession() as session:
        try:
            async with session.ws_connect(f"http://127.0.0.1:{port}/api/ws",
                                          headers=headers or {}) as ws:
                await ws.close()
                return 101
        except aiohttp.WSServerHandshakeError as e:
            return e.status


# ---- 1. DNS rebinding: the Host allow-list ------------------------------------------------
EVIL = {"Host": "evil.example:8020", "Origin": "http://evil.example:8020"}


def test_dns_rebinding_refused_on_every_route_and_the_websocket(star):
    s = star
    write = json.dumps({"object": "%MW3", "value": 5}).encode()
    force = json.dumps({"object": "%Q0.0", "value": 1}).encode()
    for method, path, body in (("POST", "/api/write", write), ("POST", "/api/force", force),
                               ("POST", "/api/control", b'{"action": "stop"}'),
                               ("GET", "/api/status", None), ("GET", "/", None),
                               ("GET", "/static/app.js", None)):
        status, text = http(s.port, method, path, body, EVIL)
        assert status == 403, (path, status, text)
        assert "evil.example:8020" in text and "--web-allow-host" in text
        status, _ = http(s.port, method, path, body, {"Host": "evil.example:8020"})
        assert status == 403, path  # the Host alone, without an Origin
    assert asyncio.run(_ws_status(s.port, EVIL)) == 403
    s.scans()
    assert s.plc["%MW3"] == 0 and s.plc.forced == {} and s.plc.state == "RUN"
    # this machine's loopback names and any address literal are served
    for host in ("localhost:1", f"127.0.0.1:{s.port}", "[::1]:8020", "192.168.1.7"):
        assert http(s.port, "GET", "/api/status", None, {"Host": host})[0] == 200, host
    # an Origin must be the page's own Host, by an allowed name
    assert http(s.port, "GET", "/api/status", None,
                {"Host": "localhost:8020", "Origin": "http://evil.example:8020"})[0] == 403


def test_allowed_host_names_are_configurable():
    s = Stack(STAR, STAR.with_suffix(".toml"), allowed_hosts=("plc.example.lan",))
    try:
        hdrs = {"Host": "PLC.example.lan:8020", "Origin": "http://PLC.example.lan:8020"}
        assert http(s.port, "POST", "/api/write", b'{"object": "%MW3", "value": 5}',
                    hdrs)[0] == 200
        assert asyncio.run(_ws_status(s.port, hdrs)) == 101
        assert http(s.port, "GET", "/api/status", None, EVIL)[0] == 403
        s.scans()
        assert s.plc["%MW3"] == 5
    finally:
        s.close()


# ---- 2. beyond loopback every route needs a token ----------------------------------------
def test_beyond_loopback_every_route_and_the_websocket_need_a_token():
    """The monitor as if bound to a LAN address (the guard's loopback flag off; the test
    still talks to 127.0.0.1 only)."""
    s = Stack(STAR, STAR.with_suffix(".toml"), token="full", read_token="look")
    try:
        s.web.server.guard.loopback = False
        port = s.port
        for path in ("/", "/static/app.js", "/api/info", "/api/status", "/api/read?obj=%MW3",
                     "/api/io", "/api/ladder/0", "/api/machine"):
            assert http(port, "GET", path)[0] == 401, path
            assert http(port, "GET", path, None, {"Authorization": "Bearer nope"})[0] == 401
            assert http(port, "GET", path, None, {"Authorization": "Bearer look"})[0] == 200
            assert http(port, "GET", path, None, {"Authorization": "Bearer full"})[0] == 200
        assert asyncio.run(_ws_status(port)) == 401
        assert asyncio.run(_ws_status(port, {"Authorization": "Bearer look"})) == 101
        # the read-only token reads, never changes
        assert http(port, "POST", "/api/read", b'{"objects": ["%MW3"]}',
                    {"Authorization": "Bearer look"})[0] == 200
        status, text = http(port, "POST", "/api/write", b'{"object": "%MW3", "value": 5}',
                            {"Authorization": "Bearer look"})
        assert status == 403 and "read-only token" in text
        assert http(port, "POST", "/api/write", b'{"object": "%MW4", "value": 6}',
                    {"Authorization": "Bearer full"})[0] == 200
        # the page opened with ?token= gets a cookie its own requests carry
        status, _, cookies = asyncio.run(_http(port, "GET", "/?token=look"))
        assert status == 200 and cookies["softplc_token"] == "look"
        assert http(port, "GET", "/api/status", None, {"Cookie": "softplc_token=look"})[0] \
            == 200
        s.scans()
        assert s.plc["%MW3"] == 0 and s.plc["%MW4"] == 6
    finally:
        s.close()


# ---- 3. sizes checked before ranges are expanded --------------------------------------------
def test_subscription_of_huge_ranges_is_refused_before_expanding(star, monkeypatch):
    expanded = []
    real = objects.expand
    monkeypatch.setattr(objects, "expand", lambda *a: expanded.append(a) or real(*a))
    star.web.controller.objects._refs.clear()
    many = [f"%MW{i}:2000" for i in range(4000)]  # 8 million objects in 56 KB

    async def talk() -> tuple[dict, dict, int | None]:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f"http://127.0.0.1:{star.port}/api/ws") as ws:
                await ws.send_str(json.dumps({"subscribe": {"objects": many}}))
                while (m := json.loads((await ws.receive(timeout=5)).data))["type"] != \
                        "error":
                    pass
                await ws.send_str(json.dumps({"subscribe": {"objects": ["%MW0:10"]}}))
                while "values" not in (ok := json.loads((await ws.receive(timeout=5)).data)):
                    pass
                # one message over the cap: closed with "message too big"
                await ws.send_str("x" * (pages.MAX_WS_MESSAGE + 1))
                while (await ws.receive(timeout=5)).type not in (
                        aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED):
                    pass
                return m, ok, ws.close_code

    err, ok, code = asyncio.run(talk())
    assert "more than 2000 objects" in err["error"]
    assert expanded == [("%MW0:10", star.plc.profile)]  # the refused ranges: never expanded
    assert len(ok["values"]) == 10
    assert code == 1009
    status, text = http(star.port, "POST", "/api/read",
                        json.dumps({"objects": many[:3000]}).encode())
    assert status == 400 and "more than 2000 objects" in text


# ---- 4. pages: a limit, and slow pages never hold up the others -------------------------
def test_pages_past_the_limit_are_closed_with_a_clear_code():
    s = Stack(STAR, STAR.with_suffix(".toml"), max_pages=3)

    async def talk() -> tuple[int | None, str]:
        async with aiohttp.ClientSession() as session:
            url = f"http://127.0.0.1:{s.port}/api/ws"
            opened = [await session.ws_connect(url) for _ in range(3)]
            for ws in opened:
                await ws.receive(timeout=5)  # served: an update comes
            extra = await session.ws_connect(url)
            msg = await extra.receive(timeout=5)
            for ws in opened:
                await ws.close()
            return extra.close_code, msg.extra or ""

    try:
        code, reason = asyncio.run(talk())
        assert code == pages.CLOSE_TOO_MANY == 1013
        assert "too many pages open: at most 3" in reason
        assert s.web.server.pages.refused == 1
    finally:
        s.close()


def test_a_page_that_never_reads_does_not_stall_the_others(star, monkeypatch):
    """Twenty pages whose sends never complete (a reader that stopped reading: the socket
    buffer is full) beside a normal page: it still gets its updates (the old server sent
    the pages in turn: none), each stalled page holds one update at most, and is dropped
    after STALL_TIMEOUT. Counted in updates, not per second: the machine's speed sets the
    rate. STALL_TIMEOUT is a hang's bound while the updates are counted, then short."""
    monkeypatch.setattr(pages, "STALL_TIMEOUT", WAIT_S)
    server = star.web.server
    updates = 5  # received by the normal page while the stalled ones are still there

    calls = []

    async def never(_text: str) -> None:
        calls.append(1)
        await asyncio.Event().wait()

    async def talk() -> set:
        async with aiohttp.ClientSession() as session:
            url = f"http://127.0.0.1:{star.port}/api/ws"
            slow = [await session.ws_connect(url) for _ in range(20)]
            sub = json.dumps({"subscribe": {"objects": ["%MW0:100"], "io": True}})
            for ws in slow:
                await ws.send_str(sub)
            while len(server.clients) < 20:
                await asyncio.sleep(0.01)
            stalled = set(server.clients)
            for c in stalled:
                c.ws.send_str = never  # as a full socket buffer does
            normal = await session.ws_connect(url)
            await normal.send_str(sub)
            n = 0
            while n < updates:  # (the old server: none, the receive times out)
                msg = json.loads((await normal.receive(timeout=WAIT_S)).data)
                n += msg.get("type") == "update"
            assert stalled <= server.clients  # all got them while the stalled pages stayed
            monkeypatch.setattr(pages, "STALL_TIMEOUT", 1.0)  # now: they are dropped
            while stalled & server.clients and (await normal.receive(timeout=WAIT_S)):
                pass  # the normal page goes on being served meanwhile
            left = stalled & server.clients
            await normal.close()
            return left

    left = asyncio.run(talk())
    assert len(calls) == 20  # one update handed to each stalled page, no more
    assert server.pages.frames_dropped > 20  # the next ones skipped
    assert left == set()  # and, stalled for over STALL_TIMEOUT, they were dropped


# ---- 5. the change queue: bounded, control commands first ---------------------------------
def test_change_queue_is_bounded_and_stop_does_not_wait(star):
    s = star
    limit = commands.MAX_PENDING
    presses = [{"object": "%I0.5", "value": k % 2} for k in range(limit)]
    with s.lock:  # no scan meanwhile: everything queued waits
        start = s.boundaries
        status, text = http(s.port, "POST", "/api/write",
                            json.dumps({"writes": presses}).encode())
        assert status == 200
        status, text = http(s.port, "POST", "/api/write", b'{"object": "%I0.6", "value": 1}')
        assert status == 503 and "try again later" in text
        assert http(s.port, "POST", "/api/force", b'{"object": "%I0.7", "value": 1}')[0] \
            == 503
        assert http(s.port, "POST", "/api/control", b'{"action": "stop"}')[0] == 200
        assert http(s.port, "POST", "/api/unforce", b"{}")[0] == 200  # its own lane too
    s.scans(3)
    with s.lock:  # what is left and how many scans took from it, read together
        pending, ran = s.web.controller.pending, s.boundaries - start
    assert s.plc.state == "STOP"
    assert limit - ran <= pending < limit  # the presses: one per scan, not all at once
    assert not s.plc["%I0.6"]  # the refused write was not queued


def test_unforce_drops_the_forcing_still_queued(star):
    s = star
    with s.lock:
        assert http(s.port, "POST", "/api/force", b'{"object": "%I0.7", "value": 1}')[0] \
            == 200
        assert http(s.port, "POST", "/api/unforce", b'{"object": "%I0.7"}')[0] == 200
    s.scans(3)
    assert s.plc.forced == {}


# ---- 6. malformed bodies: a 4xx and one log line ------------------------------------------
def test_deeply_nested_and_huge_bodies_get_4xx_and_one_log_line(star, caplog):
    caplog.set_level(logging.WARNING, "softplc.web")
    deep = b"[" * 20000 + b"]" * 20000
    deep_obj = b'{"object": ' + b"[" * 20000 + b"]" * 20000 + b"}"
    warn = star.web.server.warn
    for body, status in ((deep, 400), (deep_obj, 400), (b"x" * 100_000, 413)):
        caplog.clear()
        warn._kinds.clear()  # each case as the first of its kind
        got, text = http(star.port, "POST", "/api/write", body)
        assert got == status and "Traceback" not in text
        assert "error" in json.loads(text)
        assert len([r for r in caplog.records if r.name == "softplc.web"]) == 1
    caplog.clear()  # a flood: counted, summarised once per 10 s, not a line each
    for _ in range(20):
        assert http(star.port, "POST", "/api/write", deep)[0] == 400
    assert len(caplog.records) == 1

    async def ws_deep() -> tuple[dict, bool]:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f"http://127.0.0.1:{star.port}/api/ws") as ws:
                await ws.send_str("[" * 20000 + "]" * 20000)
                while (m := json.loads((await ws.receive(timeout=5)).data))["type"] != \
                        "error":
                    pass
                return m, not ws.closed

    err, still_open = asyncio.run(ws_deep())
    assert err["error"] and still_open


FIELDS = {"write": ("object", "value", "writes"), "force": ("object", "value"),
          "unforce": ("object",), "analog": ("object", "value", "force"),
          "control": ("action",), "read": ("objects",)}
BAD_VALUES = [None, True, -1, 2 ** 70, 1e308, "", "x", "9" * 5000, "%MW0:2000", [], [1, 2],
              {}, {"a": 1}, [[[[]]]]]


def test_wrong_types_in_every_field_never_give_a_500(star):
    async def fuzz() -> list[tuple[str, str, object, int]]:
        bad = []
        async with aiohttp.ClientSession() as session:
            for path, keys in FIELDS.items():
                for key in keys:
                    for v in BAD_VALUES:
                        body = {"object": "%MW3", "value": 1} | {key: v}
                        async with session.post(f"http://127.0.0.1:{star.port}/api/{path}",
                                                json=body) as r:
                            if r.status >= 500 or "error" not in await r.json() \
                                    and r.status != 200:
                                bad.append((path, key, v, r.status))
        return bad

    assert asyncio.run(fuzz()) == []


def test_bits_read_as_0_and_1_everywhere(star):
    """Issue 22: one JSON type per object type; a bit is 0 or 1, never true/false."""
    star.plc["%M1"] = 1
    star.plc["%MW5"] = 3
    star.scans()
    bits = ["%Q0.0:4", "%I0.0:2", "%M0:3", "%S6", "%S13", "%X1", "%TM0.Q", "%C0.D", "%C0.E",
            "%C0.F", "%MW5:X0", "%MW5:X2", "%SW0:X0"]
    status, text = http(star.port, "POST", "/api/read", json.dumps({"objects": bits}).encode())
    assert status == 200, text
    assert "true" not in text and "false" not in text
    values = json.loads(text)["values"]
    assert len(values) == 19 and all(type(v) is int and v in (0, 1) for v in values.values())
    assert values["%M1"] == 1 and values["%MW5:X0"] == 1 and values["%MW5:X2"] == 0


def test_run_takes_allowed_hosts_and_page_limit_from_the_config(tmp_path):
    import sys

    from softplc.errors import ConfigError
    from softplc.plc import PLC

    sys.path.insert(0, str(ROOT / "tests"))
    from daemon_util import Daemon

    cfg = tmp_path / "star.toml"
    symbols = STAR.parent / "star_delta_symbols.csv"  # the config's symbols_file, beside it
    (tmp_path / symbols.name).write_bytes(symbols.read_bytes())
    cfg.write_text(STAR.with_suffix(".toml").read_text()
                   + '\n[web]\nallowed_hosts = ["plc.lan"]\nmax_pages = 1\n')
    d = Daemon(tmp_path, "--config", str(cfg), "--web", "0", "--stats-interval", "0",
               program=STAR)
    try:
        port = d.web_port()
        assert http(port, "GET", "/api/status", None, {"Host": "plc.lan:80"})[0] == 200
        assert http(port, "GET", "/api/status", None, {"Host": "plc.lan.evil:80"})[0] == 403

        async def two_pages() -> int | None:
            async with aiohttp.ClientSession() as session:
                url = f"http://127.0.0.1:{port}/api/ws"
                async with session.ws_connect(url) as first:
                    await first.receive(timeout=5)
                    async with session.ws_connect(url) as second:
                        await second.receive(timeout=5)
                        return second.close_code

        assert asyncio.run(two_pages()) == 1013
    finally:
        assert d.stop() == 0
    with pytest.raises(ConfigError, match="web.max_pages"):
        PLC.from_file(STAR, config={"web": {"max_pages": 0}})


def test_forcing_bursts_recompile_at_most_twice_per_scan(star, monkeypatch):
    """Forcing a new object and unforcing recompile the program (2-14 ms each in the scan
    thread): a burst of them is spread over scans, and an unforce of nothing is free."""
    s, per_scan = star, [0]
    real = s.plc.replace_program

    def counted(*a: object, **k: object) -> None:
        per_scan[-1] += 1
        real(*a, **k)

    monkeypatch.setattr(s.plc, "replace_program", counted)
    s.plc.before_scan.insert(0, lambda: per_scan.append(0))
    with s.lock:
        for _ in range(20):  # nothing is forced: no recompiling at all
            assert http(s.port, "POST", "/api/unforce", b"{}")[0] == 200
    s.scans(3)
    assert sum(per_scan) == 0
    with s.lock:
        assert http(s.port, "POST", "/api/force",
                    b'{"object": "%M10:40", "value": 1}')[0] == 200
        assert http(s.port, "POST", "/api/unforce", b'{"object": "%M10"}')[0] == 200
    until(lambda: not s.web.controller.pending)  # (scans go on: s's thread)
    s.scans(2)
    # 39 forcings: the unforce dropped %M10's queued forcing, and had nothing to release
    assert max(per_scan) <= 2 and sum(per_scan) == 39
    assert len(s.plc.forced) == 39 and "%M10" not in s.plc.forced
