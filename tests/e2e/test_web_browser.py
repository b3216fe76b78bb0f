"""The web monitor in a real browser: Debian's headless Chromium driven by Playwright
(tests/chromium.py: the browser, one per test worker; `module_page`: one page per test
module, which each test navigates to its monitor). Screenshots go to out/ and are checked
for content.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest
from chromium import CHROMIUM, MISSING, sync_api
from daemon_util import ROOT, Daemon, started
from waits import PAGE_POLL_MS, WAIT_MS, WAIT_S, until

from softplc.commands.io import Client
from softplc.runtime.blocks import MAX_VALUE

if CHROMIUM is None:
    pytest.skip(MISSING, allow_module_level=True)

OUT = ROOT / "out"
PROGRAMS = ROOT / "ladder_programs"
MBPOLL = shutil.which("mbpoll")


def web_url(d: Daemon) -> str:
    line = next(x for x in d.out if "web monitor on" in x)
    return re.search(r"(http://\S+/)", line)[1]


def start(daemons: list[Daemon], tmp_path: Path, name: str,
          *args: str) -> tuple[Daemon, str, Client]:
    """The example ladder_programs/`name`.il with its .toml under a daemon, its web monitor
    on a free port: the daemon, the page's URL and an API client (`daemons` kills it)."""
    d = started(daemons, tmp_path, "--config", str(PROGRAMS / f"{name}.toml"), "--web", "0",
                "--stats-interval", "0", *args, program=PROGRAMS / f"{name}.il")
    url = web_url(d)
    return d, url, api_of(url)


VIEWPORT = {"width": 1400, "height": 900}


@pytest.fixture(scope="module", name="module_page")
def _module_page(browser):
    """One page for the module's tests, each navigating it to its monitor (`open_page`): a
    new page is a browser context and a renderer process of its own, about 1.4 s more
    Chromium CPU than a navigation (docs/performance.md). Closed at the module's end."""
    p = browser.new_page(viewport=VIEWPORT)
    p.set_default_timeout(WAIT_MS)  # its waits too
    # confirm() of RUN/STOP accepted; prompt() of a force answers 1
    p.on("dialog", lambda d: d.accept("1") if d.type == "prompt" else d.accept())
    yield p
    p.close()


def clear_origin(page, url: str) -> None:
    """Forget what an earlier test kept in the browser for `url`'s origin (the tables and
    the trends' objects in localStorage, a token), as a new page would."""
    cdp = page.context.new_cdp_session(page)
    try:
        cdp.send("Storage.clearDataForOrigin", {"origin": re.match(r"https?://[^/]+", url)[0],
                                                "storageTypes": "all"})
    finally:
        cdp.detach()


def open_page(page, url: str):
    """`page` (the module's) on the monitor at `url`, as a new page would find it
    (`clear_origin`); the old monitor's websocket closes with the navigation."""
    clear_origin(page, url)
    page.set_viewport_size(VIEWPORT)
    page.goto(url)
    page.wait_for_selector("#link.up")
    return page


def shot(page, name: str) -> Path:
    """A screenshot in out/, checked to show something (not one flat colour)."""
    import numpy as np
    from matplotlib import image

    OUT.mkdir(exist_ok=True)
    path = OUT / f"web-{name}.png"
    page.screenshot(path=str(path))
    px = image.imread(str(path))[::2, ::2, :3]
    rgb = (px * 255).astype(np.uint32)
    colours = len(np.unique(rgb[..., 0] << 16 | rgb[..., 1] << 8 | rgb[..., 2]))
    assert colours > 20 and px.std() > 0.05, f"{path} looks blank"
    return path


def led(page, addr: str):
    return page.locator(f'#modules .io[data-addr="{addr}"] .led')


def push(page, addr: str, hold_ms: int = 150) -> None:
    button = page.locator(f'#modules .io[data-addr="{addr}"] button.push')
    button.hover()
    page.mouse.down()
    page.wait_for_timeout(hold_ms)
    page.mouse.up()


@pytest.fixture(scope="module")
def star_daemon(tmp_path_factory):
    d = Daemon(tmp_path_factory.mktemp("star"), "--config", str(PROGRAMS / "star_delta.toml"),
               "--web", "0", "--stats-interval", "0",
               program=PROGRAMS / "star_delta.il")
    yield d
    d.kill()


def api_of(url: str) -> Client:
    """The monitor's API at `url` (`softplc io`'s client)."""
    return Client("127.0.0.1", int(re.search(r":(\d+)/$", url)[1]))


# star_delta.toml's star time (%TM0.P, 5 s): the test holds the star phase with the largest
# preset (the page must show it however late its updates come on a loaded machine) and
# ends it with the smallest one, then puts the configured one back for the module's tests
STAR_PRESET = tomllib.loads((PROGRAMS / "star_delta.toml").read_text())["timers"]["%TM0"][
    "preset"]


def test_star_delta_from_the_simulation_panel(module_page, star_daemon):
    page = open_page(module_page, web_url(star_daemon))
    api = api_of(web_url(star_daemon))
    api.set("%TM0.P", MAX_VALUE)  # the star time runs until the test ends it
    try:
        star_then_delta(page, api)
    finally:
        api.set("%TM0.P", STAR_PRESET)


def star_then_delta(page, api: Client) -> None:
    """The Simulation tab starts the motor: star until the test ends the star time, then
    delta; a forced input; the live ladder (`api`: the daemon's monitor API)."""
    sw = page.locator
    sw('#modules .io[data-addr="%I0.1"] button.toggle').click()  # stop button: NC, closed
    sw('#modules .io[data-addr="%I0.2"] button.toggle').click()  # overload relay: NC, OK
    push(page, "%I0.3")  # fault reset
    sync_api.expect(led(page, "%I0.2")).to_have_class(re.compile(r"\bon\b"))
    sync_api.expect(led(page, "%Q0.3")).not_to_have_class(re.compile(r"\bon\b"))
    push(page, "%I0.0")  # start push button
    sync_api.expect(led(page, "%Q0.0")).to_have_class(re.compile(r"\bon\b"), timeout=WAIT_MS)
    sync_api.expect(led(page, "%Q0.1")).to_have_class(re.compile(r"\bon\b"), timeout=WAIT_MS)
    assert "on" not in led(page, "%Q0.2").get_attribute("class").split()
    sync_api.expect(led(page, "%I0.0")).not_to_have_class(re.compile(r"\bon\b"))  # released
    assert "on" in led(page, "%Q0.1").get_attribute("class").split()  # star held
    api.set("%TM0.P", 1)  # the star time is over at the next scan: delta after the dead time
    sync_api.expect(led(page, "%Q0.2")).to_have_class(re.compile(r"\bon\b"), timeout=WAIT_MS)
    sync_api.expect(led(page, "%Q0.1")).not_to_have_class(re.compile(r"\bon\b"))

    # force an input: the F button, prompt answered 1; the marker shows, the switch locks
    row = sw('#modules .io[data-addr="%I0.5"]')
    row.locator("button.f").click()
    sync_api.expect(row).to_have_class(re.compile(r"\bforced\b"))
    assert row.locator(".forced-mark").is_visible()
    assert row.locator("button.toggle").is_disabled()
    assert sw("#forcedcount").inner_text() == "1"
    shot(page, "simulation")  # delta on, %I0.5 forced
    row.locator("button.f").click()  # forced: the same button unforces
    sync_api.expect(row).not_to_have_class(re.compile(r"\bforced\b"))

    # live ladder: rung 5 (delta) powered through to %Q0.2
    page.click("#tabs button[data-tab=ladder]")
    page.fill("#rung-filter", "%q0.2")  # where is the delta contactor used?
    shown = [li.get_attribute("data-rung") for li in sw("#rung-list li:visible").all()]
    assert shown == ["4", "5", "8"], shown
    page.fill("#rung-filter", "")
    page.click("#rung-list li[data-rung='4']")
    rung5 = sw('#ladder div[data-rung="5"] svg')
    sync_api.expect(rung5).to_be_visible()
    assert rung5.locator("line.on").count() >= 3
    shot(page, "ladder")


@pytest.mark.skipif(MBPOLL is None, reason="mbpoll is not installed (Debian package mbpoll)")
def test_animation_table_write_read_back_with_mbpoll(module_page, star_daemon):
    page = open_page(module_page, web_url(star_daemon))
    page.click("#tabs button[data-tab=tables]")
    page.fill("#table-add", "%MW3, %MW10:2, %TM0, %MF40")
    page.click("#table-add-btn")
    row = page.locator('#anim tr[data-obj="%MW3"]')
    row.locator("input.w").fill("4321")
    row.locator("button.write").click()
    sync_api.expect(row.locator(".val")).to_have_text("4321")
    out = subprocess.run([MBPOLL, "-m", "tcp", "-p", str(star_daemon.port), "-0", "-1",
                          "-o", "2", "-t", "4", "-r", "3", "127.0.0.1"],
                         capture_output=True, text=True, timeout=WAIT_S)
    assert re.search(r"^\[3\]:\s+4321$", out.stdout, re.M), out.stdout + out.stderr
    row.locator("select").select_option("hex")
    sync_api.expect(row.locator(".val")).to_have_text("16#10E1")
    assert "P=50" in page.locator('#anim tr[data-obj="%TM0"] .val').inner_text()
    shot(page, "tables")
    # trends of two objects
    page.click("#tabs button[data-tab=trends]")
    page.fill("#trend-add", "%MW11 %MW3")
    page.click("#trend-add-btn")
    page.wait_for_timeout(1200)
    shot(page, "trends")


def test_drawing_table_machine_view(module_page, tmp_path, daemons):
    _, url, api = start(daemons, tmp_path, "drawing_table", "--speed", "4")
    page = open_page(module_page, url)
    page.click("#tabs button[data-tab=machine]")
    sync_api.expect(page.locator("#table-outline")).to_be_visible()
    until(lambda: api.get("%MW3")["%MW3"] == 0 and page.locator("#pen-path").count() == 0
          and api.request("machine?since=0")["devices"]["X"]["pos"] == 0
          and api.request("machine?since=0")["devices"]["Z"]["pos"] == 0,
          period=0.05)  # homing done: both axes at 0
    assert_view_unchanged(page, "#tab-machine")  # at rest: its updates change no element
    api.request("write", {"writes": [{"object": "%MW0", "value": 600},
                                     {"object": "%MW1", "value": 400},
                                     {"object": "%MW5", "value": 1}]})
    api.set("%MW3", 120)  # start the segment, as the host does
    path = page.locator("#pen-path")
    sync_api.expect(path).to_have_count(1, timeout=WAIT_MS)
    page.wait_for_function(
        "() => { const p = document.querySelector('#pen-path');"
        " return p && p.getTotalLength() > 100; }", timeout=WAIT_MS, polling=PAGE_POLL_MS)
    shot(page, "machine")


UPDATES_WATCHED = 5  # websocket updates the page takes while a view is watched


def assert_view_unchanged(page, view: str) -> None:
    """The page takes UPDATES_WATCHED updates with the machine's state while nothing in
    `view` changes (a MutationObserver on it): an update equal to the last one shown is no
    DOM work, so no style, layout or repaint either."""
    page.evaluate("""(view) => {
        window.viewChanges = []; window.machineUpdates = 0;
        new MutationObserver((ms) => { for (const m of ms) window.viewChanges.push(
            (m.target.id || m.target.nodeName) + " " + m.type); })
          .observe(document.querySelector(view),
                   {subtree: true, childList: true, attributes: true, characterData: true});
        const ws = state.ws, on = ws.onmessage;
        ws.onmessage = (ev) => {
            on(ev); if (ev.data.includes('"machine"')) window.machineUpdates++; };
    }""", view)
    page.wait_for_function(f"() => window.machineUpdates >= {UPDATES_WATCHED}",
                           polling=PAGE_POLL_MS)
    page.wait_for_timeout(0)  # the observer's records of the last update are delivered
    assert page.evaluate("window.viewChanges") == []


def set_hidden(page, hidden: bool) -> None:
    """The page as the browser hides it (another tab in front) or shows it again: its
    document's `hidden` and `visibilityState`, then the `visibilitychange` event (a headless
    browser's pages are all shown)."""
    page.evaluate("""(hidden) => {
        if (hidden) for (const [k, v] of [["hidden", true], ["visibilityState", "hidden"]])
          Object.defineProperty(document, k, {get: () => v, configurable: true});
        else { delete document.hidden; delete document.visibilityState; }
        document.dispatchEvent(new Event("visibilitychange"));
    }""", hidden)


def test_hidden_page_asks_for_the_status_alone(module_page, star_daemon):
    """A hidden page asks the daemon for the status alone: while it stays hidden its
    updates carry no I/O and no rung, and the link stays up; shown again, the I/O and the
    live rungs come back."""
    page = open_page(module_page, web_url(star_daemon))
    page.click("#tabs button[data-tab=ladder]")
    page.evaluate("""() => { window.updates = []; const ws = state.ws, on = ws.onmessage;
        ws.onmessage = (ev) => {
            on(ev); window.updates.push(Object.keys(JSON.parse(ev.data)).sort().join(" ")); };
    }""")
    page.wait_for_function("() => updates.some((k) => k.includes('io'))", polling=PAGE_POLL_MS)
    set_hidden(page, True)
    page.wait_for_function("() => updates.at(-1) === 'status type'", polling=PAGE_POLL_MS)
    seen = page.evaluate("updates.length")
    page.wait_for_function(f"() => updates.length >= {seen + UPDATES_WATCHED}",
                           polling=PAGE_POLL_MS)
    assert set(page.evaluate(f"updates.slice({seen})")) == {"status type"}
    assert page.locator("#link.up").count() == 1
    assert page.locator("#state").inner_text() != "DISCONNECTED"
    set_hidden(page, False)
    page.wait_for_function("() => updates.at(-1).includes('io')", polling=PAGE_POLL_MS)
    page.wait_for_function(f"() => updates.slice({seen}).some((k) => k.includes('ladder'))",
                           polling=PAGE_POLL_MS)
    sync_api.expect(page.locator('#ladder div[data-rung="0"] svg')).to_be_visible()


def test_analog_slider_reaches_the_plc(module_page, tmp_path, daemons):
    """analog_thermostat: the base's potentiometer %IW0.0 is a slider; the program copies it
    to %MW0 (/4). The PT100 %IW2.0 follows the oven (slider locked), %QW2.0 is a value."""
    _, url, api = start(daemons, tmp_path, "analog_thermostat")
    page = open_page(module_page, url)
    pot = page.locator('#analog .aio[data-addr="%IW0.0"]')
    assert pot.locator(".lo").inner_text() == "0" and pot.locator(".hi").inner_text() == "1"
    pot.locator("input[type=range]").fill("0.5")  # input + change, as a drag released
    until(lambda: api.get("%MW0")["%MW0"] == 128, period=0.05)
    assert api.get("%IW0.0", "%MW0") == {"%IW0.0": 512, "%MW0": 128}  # 0.5 * 1023, / 4
    sync_api.expect(pot.locator(".aword")).to_have_text("(%IW0.0 = 512)")
    sync_api.expect(pot.locator(".aval")).to_have_text("0.5")
    pt100 = page.locator('#analog .aio[data-addr="%IW2.0"]')
    assert pt100.locator("input[type=range]").is_disabled()  # the oven drives it
    assert "°C" in pt100.locator(".aval").inner_text()
    spare = page.locator('#analog .aio[data-addr="%IW2.1"]')  # not in [analog]
    sync_api.expect(spare.locator(".aval")).to_have_text("no signal")
    sync_api.expect(spare.locator(".aword")).to_have_text("(%IW2.1 = 0)")
    assert spare.locator("input[type=range]").is_disabled()
    heater = page.locator('#analog .aio.out[data-addr="%QW2.0"]')
    sync_api.expect(heater.locator(".aval")).to_have_text(re.compile(r"^(10|0) V$"))
    assert heater.locator("input").count() == 0
    shot(page, "analog")


def test_animation_table_of_output_bits_survives_any_value_and_resets(module_page, star_daemon):
    """An output range in an animation table (issue 22): bits read 0/1, a value of any
    type (true, a string, NaN) shows as text instead of stopping the page's updates, a
    malformed saved table is dropped, and "Reset tables" clears what the browser kept."""
    page = open_page(module_page, web_url(star_daemon))
    page.click("#tabs button[data-tab=tables]")
    page.fill("#table-add", "%Q0.0:4, %M1")
    page.click("#table-add-btn")
    for obj in ("%Q0.0", "%Q0.3", "%M1"):
        sync_api.expect(page.locator(f'#anim tr[data-obj="{obj}"] .val')).to_have_text(
            re.compile(r"^[01]$"))
    shown = page.evaluate("""() => {
        const odd = {"%Q0.0": true, "%Q0.1": "x", "%Q0.2": NaN, "%M1": [1]};
        Object.assign(state.values, odd); showTable();
        return Object.keys(odd).map((o) => $(`#anim tr[data-obj="${o}"] .val`).textContent);
    }""")
    assert shown == ["1", "x", "NaN", "0=1"]
    scans = int(page.locator("#scans").inner_text())
    page.wait_for_function(f"() => +document.querySelector('#scans').textContent > {scans}",
                           polling=PAGE_POLL_MS)
    page.reload()  # the table is kept in the browser: the page still works with it
    page.wait_for_selector("#link.up")
    page.click("#tabs button[data-tab=tables]")
    sync_api.expect(page.locator('#anim tr[data-obj="%Q0.1"] .val')).to_have_text(
        re.compile(r"^[01]$"))
    page.click("#table-reset")  # confirm() accepted
    sync_api.expect(page.locator("#anim tbody tr")).to_have_count(0)
    assert page.evaluate("() => localStorage.getItem('softplc.tables')") is None
    # a malformed saved table (an older page's, or edited by hand) is dropped on load
    page.evaluate("() => localStorage.setItem('softplc.tables', '[{\"name\": 1, \"rows\": 5}]')")
    page.reload()
    page.wait_for_selector("#link.up")
    assert page.locator("#table-select option").all_inner_texts() == ["Table 1"]


def test_page_beyond_loopback_with_the_read_only_token(module_page):
    """The monitor as if bound to a LAN address (the guard's loopback flag off; the page
    still talks to 127.0.0.1): without a token the page is refused; opened with the
    read-only token's URL it runs (its files, API reads and websocket carry the cookie)
    and a write is refused with a message."""
    from test_web_api import STAR, Stack

    s = Stack(STAR, STAR.with_suffix(".toml"), token="full", read_token="look")
    try:
        s.web.server.guard.loopback = False
        page = module_page
        clear_origin(page, f"http://127.0.0.1:{s.port}/")
        assert page.goto(f"http://127.0.0.1:{s.port}/").status == 401
        assert page.goto(f"http://127.0.0.1:{s.port}/?token=look").status == 200
        page.wait_for_selector("#link.up")
        page.click("#tabs button[data-tab=tables]")
        page.fill("#table-add", "%MW3")
        page.click("#table-add-btn")
        row = page.locator('#anim tr[data-obj="%MW3"]')
        sync_api.expect(row.locator(".val")).to_have_text("0")
        row.locator("input.w").fill("7")
        row.locator("button.write").click()
        sync_api.expect(page.locator("#message")).to_have_text(
            "the read-only token cannot change anything")
        s.scans()
        assert s.plc["%MW3"] == 0
    finally:
        module_page.context.clear_cookies()  # the token's: 127.0.0.1's, whatever the port
        s.close()
