"""The Machine tab's views of the servo table, the cutting table and the machining centre,
trends with bits and words of very different ranges, and the header when the daemon stops,
in headless Chromium (the set-up of test_web_browser.py). Screenshots go to out/."""

from __future__ import annotations

import re
import signal
import time

import pytest
from daemon_util import started
from test_web_browser import (
    PROGRAMS,
    _module_page,  # noqa: F401 (the module_page fixture)
    open_page,
    shot,
    start,
    sync_api,
    web_url,
)
from waits import PAGE_POLL_MS, WAIT_MS, WAIT_S


def machine_tab(page) -> None:
    page.click("#tabs button[data-tab=machine]")


def test_servo_table_view_follows_homing(module_page, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "servo_table", "--speed", "2")
    page = open_page(module_page, url)
    machine_tab(page)
    sync_api.expect(page.locator("#carriage")).to_be_visible()
    assert "X = -19.531 mm" in page.locator("#machine-hint").inner_text()  # -8000 counts
    api.set("%I0.1", 1)  # start: the contactor closes, the loops close
    api.set("%I0.1", 0)
    api.set("%MW100", 2)  # home X then Y: the axes move, the FE moves
    page.wait_for_function(
        "() => /X = 0\\.0\\d\\d mm/.test(document.querySelector('#machine-hint')"
        ".textContent)", timeout=WAIT_MS, polling=PAGE_POLL_MS)
    fe = page.locator('#fe-chart polyline.fe-line[data-axis="X"]')
    pts = [tuple(map(float, p.split(","))) for p in fe.get_attribute("points").split()]
    assert len({y for _, y in pts}) > 3  # the FE of the homing move is not flat
    assert page.locator("#axes-trail").count() == 1
    shot(page, "machine-servo")


# the cut's box in the drawing's own units (read in one go: the view is redrawn each update)
PATH_BOX = """() => { const b = document.querySelector('#pen-path').getBBox();
  return [b.x, b.y, b.width, b.height]; }"""


def test_cutting_table_view_draws_the_cut_and_the_torch(module_page, tmp_path, daemons):
    """A square streamed by the host (softplc.machines.cutting.client) at full speed: the view
    draws what the torch cut (#pen-path) apart from the moves with the torch off."""
    from softplc.machines.cutting import load_piece
    from softplc.machines.cutting.client import CutClient

    text = (PROGRAMS / "cutting_table.toml").read_text(encoding="utf-8")
    text = text.replace("start = 12340000.0", "start = 100000.0") \
        .replace("start = 5700000.0", "start = 100000.0")  # 1 mm from the switches: short homing
    machine = tmp_path / "machine.toml"
    machine.write_text(text, encoding="utf-8")
    d = started(daemons, tmp_path, "--config", str(machine), "--web", "0", "--speed", "max",
                "--stats-interval", "0", program=PROGRAMS / "cutting_table.il")
    page = open_page(module_page, web_url(d))
    errors: list[str] = []

    def page_error(e) -> None:
        errors.append(str(e))

    def console_error(m) -> None:
        if m.type == "error":
            errors.append(m.text)
    page.on("pageerror", page_error)
    page.on("console", console_error)
    machine_tab(page)
    sync_api.expect(page.locator("#tool")).to_be_visible()
    piece = load_piece(PROGRAMS / "pieces" / "cuadrado.toml", speed=10.0, move_speed=10.0)
    with CutClient("127.0.0.1", d.port, progress=None, poll_interval=0.01) as client:
        res = client.stream(piece)
    assert res.done == len(piece.segments())
    page.wait_for_function(
        "() => { const p = document.querySelector('#pen-path');"
        " return p && p.getTotalLength() > 80; }", timeout=WAIT_MS, polling=PAGE_POLL_MS)
    # the 15 mm square: about 25 px (read in one go: the element is redrawn each update)
    box = page.evaluate("""() => { const r = document.querySelector('#pen-path')
      .getBoundingClientRect(); return { width: r.width, height: r.height }; }""")
    assert 20 < box["width"] < 40 and abs(box["width"] - box["height"]) < 2, box
    assert page.locator("#travel-path").count() == 1  # homing and the move to the start
    assert errors == []  # (a machine message without devices threw in machineHistory)
    # the cut is over; work coordinates, as the host reports them (res.pos_mm: the PLC's
    # %MD112 / %MD114)
    sync_api.expect(page.locator("#machine-hint")).to_contain_text(
        f"X = {res.pos_mm[0]:.3f} mm, Y = {res.pos_mm[1]:.3f} mm (work coordinates, as the "
        "host reports them; machine: ", timeout=WAIT_MS)
    assert "torch off;" in page.locator("#machine-hint").inner_text()
    assert "X (mm, work)" in page.locator("#table-view").inner_html()
    area, outline = page.evaluate("""() => ['#work-area', '#table-outline'].map(
      (s) => document.querySelector(s).getBBox().width)""")
    assert area == pytest.approx(outline * 240 / 305, abs=1)  # of the travel, -5..300 mm
    rows = {r.locator("td").first.inner_text(): r.inner_text()
            for r in page.locator("#devices tbody tr").all()}
    assert "drive_homed=false" in rows["X"]  # the drive's own homing did not run...
    assert "homed (program, %M110)=true" in rows["trace"]  # ...the program homed the table
    shot(page, "machine-cutting")
    drawn = page.evaluate(PATH_BOX)
    page.remove_listener("pageerror", page_error)  # the module's page: the next tests' own
    page.remove_listener("console", console_error)

    # a page opened after the cut catches up; its first update split in two chunks shows
    # the loading indicator, then the whole cut
    page = open_page(module_page, web_url(d))
    page.evaluate("""() => { const orig = showMachine; window.loading = [];
      showMachine = (m) => {
        if (m.trace_from !== 0 || m.trace.length < 4) return orig(m);
        const k = m.trace.length >> 1;
        orig({ ...m, trace: m.trace.slice(0, k), trace_next: m.trace_next >> 1 });
        const el = document.querySelector("#trace-loading");
        window.loading.push(el ? el.textContent : "");
        orig({ ...m, trace_from: m.trace_next >> 1, trace: m.trace.slice(k) });
        window.loading.push(document.querySelector("#trace-loading") ? "still" : "");
      }; }""")
    machine_tab(page)
    page.wait_for_function("() => window.loading.length === 2", timeout=WAIT_MS,
                           polling=PAGE_POLL_MS)
    first, after = page.evaluate("window.loading")
    assert re.fullmatch(r"loading the trace: 50 % \(\d+ of \d+ samples\)…", first), first
    assert after == ""
    # the same cut (the updates' chunks differ, so do the samples thinned out of them)
    assert page.evaluate(PATH_BOX) == pytest.approx(drawn, abs=1)


def test_machining_centre_view_shows_axis_step_and_estimate(module_page, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "mass_tuning", "--speed", "4")
    page = open_page(module_page, url)
    machine_tab(page)
    step = page.locator("#machine-step")
    sync_api.expect(step).to_have_text(re.compile(r"^step 0 \(initial\)"))
    assert "no estimate yet" in page.locator("#machine-estimate").inner_text()
    api.set("%M205", 1)  # automatic mode from the HMI, then the softkey
    api.set("%M200", 1)
    sync_api.expect(step).to_have_text(re.compile(r"^step [12]:"), timeout=WAIT_MS)
    # the axis runs to Q26 (-480 mm): the carriage moves left on the travel
    page.wait_for_function(
        "() => { const m = /X = (-?[\\d.]+) mm/.exec(document.querySelector("
        "'#table-view').textContent); return m && +m[1] < -20; }", timeout=WAIT_MS,
        polling=PAGE_POLL_MS)
    # the host's answer, as softplc tune writes it: mass, uncertainty, row, then EST_ACK
    api.request("write", {"writes": [{"object": "%MF406", "value": 22650.5},
                                     {"object": "%MF408", "value": 310.0},
                                     {"object": "%MW404", "value": 3},
                                     {"object": "%MW402", "value": 1}]})
    est = page.locator("#machine-estimate")
    sync_api.expect(est).to_contain_text("22650.5 kg", timeout=WAIT_MS)
    assert "± 310.0 kg" in est.inner_text()
    shot(page, "machine-centre")


# pixels of `colour` (#rrggbb) in the canvas rows [top, top + height) of the plot
COUNT_COLOUR = """([top, height, colour]) => {
  const cv = document.querySelector('#trend'), g = cv.getContext('2d');
  const px = g.getImageData(90, top, cv.width - 90 - 230, height).data;
  const want = [1, 3, 5].map((i) => parseInt(colour.slice(i, i + 2), 16));
  let n = 0;
  for (let i = 0; i < px.length; i += 4)
    if (Math.abs(px[i] - want[0]) < 8 && Math.abs(px[i + 1] - want[1]) < 8
        && Math.abs(px[i + 2] - want[2]) < 8) n++;
  return n;
}"""


def test_trends_give_bits_lanes_and_words_their_own_axes(module_page, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "star_delta")
    page = open_page(module_page, url)
    page.click("#tabs button[data-tab=trends]")
    first = {"%MD100": -500000, "%MW120": 3, "%M100": 1}
    for n, (pos, step, bit) in enumerate(((-500000, 3, 1), (480000, 27, 0),
                                          (-500000, 12, 1))):
        api.request("write", {"writes": [{"object": "%MD100", "value": pos},
                                         {"object": "%MW120", "value": step},
                                         {"object": "%M100", "value": bit}]})
        if n == 0:  # trend from the first values on: under load the page could
            # otherwise sample the zeros before the first write reached the PLC
            deadline = time.monotonic() + WAIT_S
            while api.get(*first) != first and time.monotonic() < deadline:
                time.sleep(0.05)
            page.fill("#trend-add", "%MD100 %MW120 %M100")
            page.click("#trend-add-btn")
        page.wait_for_timeout(600)
    layout = page.evaluate("() => state.trend.layout")
    kinds = {x["object"]: x for x in layout}
    assert kinds["%M100"]["kind"] == "bit" and kinds["%MD100"]["kind"] == "word"
    # each word on its own axis, over its own real range
    assert (kinds["%MD100"]["min"], kinds["%MD100"]["max"]) == (-500000, 480000)
    assert (kinds["%MW120"]["min"], kinds["%MW120"]["max"]) == (3, 27)
    for x in layout:  # each trace drew in its own strip or lane, and not flat
        n = page.evaluate(COUNT_COLOUR, [x["top"], x["height"], x["colour"]])
        assert n > 100, (x, n)
    bit = kinds["%M100"]
    rows = page.evaluate("""([top, h, colour]) => {
      const g = document.querySelector('#trend').getContext('2d');
      const want = [1, 3, 5].map((i) => parseInt(colour.slice(i, i + 2), 16));
      const hit = [];
      for (let y = top; y < top + h; y++) {
        const px = g.getImageData(90, y, 780, 1).data;
        for (let i = 0; i < px.length; i += 4)
          if (Math.abs(px[i] - want[0]) < 8 && Math.abs(px[i + 1] - want[1]) < 8
              && Math.abs(px[i + 2] - want[2]) < 8) { hit.push(y); break; }
      }
      return hit; }""", [bit["top"], bit["height"], bit["colour"]])
    assert max(rows) - min(rows) >= bit["height"] - 14  # steps between 0 and 1
    shot(page, "trends-lanes")


STALE_TEST_MS = 1000  # ten updates missed (the daemon pushes 10 a second, docs/web.md)


def test_header_says_disconnected_and_reconnects(module_page, tmp_path, daemons):
    d, url, _ = start(daemons, tmp_path, "star_delta")
    port = re.search(r":(\d+)/$", url)[1]
    page = open_page(module_page, url)
    state = page.locator("#state")
    sync_api.expect(state).to_have_text("RUN")
    # a daemon that hangs (SIGSTOP): the socket stays open but nothing comes; the page
    # says so after link.staleMs without an update (4 s; shortened here: the test checks
    # that it says so, not how long it waits)
    page.evaluate(f"() => {{ link.staleMs = {STALE_TEST_MS}; }}")
    d.proc.send_signal(signal.SIGSTOP)
    try:
        sync_api.expect(state).to_have_text("DISCONNECTED", timeout=WAIT_MS)
        assert "no update for" in state.get_attribute("title")  # (the next update clears it)
    finally:
        d.proc.send_signal(signal.SIGCONT)
    page.evaluate("() => { link.staleMs = STALE_MS; }")  # the page's own from here on
    sync_api.expect(state).to_have_text("RUN", timeout=WAIT_MS)  # updates again: live
    sync_api.expect(page.locator("#link")).to_have_class(re.compile(r"\bup\b"))  # the dot too
    assert page.evaluate("() => link.up")  # and a second hang would be told again
    d.stop()  # Ctrl-C: the daemon ends, its websocket closes
    sync_api.expect(state).to_have_text("DISCONNECTED", timeout=WAIT_MS)
    assert "disconnected" in page.locator("body").get_attribute("class")
    colour = "e => getComputedStyle(e).backgroundColor"
    assert state.evaluate(colour) == "rgb(90, 101, 112)"  # grey, not RUN's green
    shot(page, "disconnected")
    # the daemon comes back on the same port: the page reconnects by itself
    started(daemons, tmp_path, "--config", str(PROGRAMS / "star_delta.toml"), "--web", port,
            "--stats-interval", "0", program=PROGRAMS / "star_delta.il")
    sync_api.expect(state).to_have_text("RUN", timeout=WAIT_MS)
    assert state.evaluate(colour) != "rgb(90, 101, 112)"
    assert "disconnected" not in (page.locator("body").get_attribute("class") or "")


def test_a_write_the_axis_refuses_is_refused_where_it_was_made(module_page, tmp_path, daemons):
    """%MF328 is the servo table's X Ixx30 (kp): -5 is out of its range. The animation
    table's row says so in red (not a green "queued"), `softplc io set` fails with the same
    reason, a Modbus host gets exception 03; the value in force stays."""
    import struct
    import subprocess
    import sys

    from softplc.modbus.rawclient import ModbusExceptionReply, RawClient

    d, url, api = start(daemons, tmp_path, "servo_table")
    page = open_page(module_page, url)
    page.click("#tabs button[data-tab=tables]")
    page.fill("#table-add", "%MF328")
    page.click("#table-add-btn")
    row = page.locator('#anim tr[data-obj="%MF328"]')
    sync_api.expect(row.locator(".val")).not_to_have_text("…")
    kp = row.locator(".val").inner_text()
    row.locator("input.w").fill("-5")
    row.locator("button.write").click()
    note = row.locator(".write-note")
    sync_api.expect(note).to_contain_text("%MF328 := -5 refused: device 'X': Ixx30 (kp) = -5:")
    assert note.evaluate("e => getComputedStyle(e).color") == "rgb(198, 40, 40)"  # --halt
    assert "refused" in row.locator("input.w").get_attribute("class")
    assert "queued" not in page.locator("#message").inner_text()
    shot(page, "write-refused")
    row.locator("input.w").fill("7000")  # a value the axis takes: queued, the note goes
    row.locator("button.write").click()
    sync_api.expect(row.locator(".val")).to_have_text("7000")
    sync_api.expect(note).to_be_hidden()
    assert kp != "7000"

    web_port = url.rstrip("/").rsplit(":", 1)[1]
    r = subprocess.run([sys.executable, "-m", "softplc", "io", "--port", web_port, "set",
                        "%MF328", "-5"], capture_output=True, text=True, timeout=WAIT_S)
    assert r.returncode != 0 and "%MF328 := -5 refused: device 'X': Ixx30 (kp)" in r.stderr, r
    wire = struct.unpack(">2H", struct.pack(">f", -5.0))  # %MF: low word first (twido.md)
    with RawClient("127.0.0.1", d.port) as mb:
        try:
            mb.write_registers(328, [wire[1], wire[0]])
            raise AssertionError("a value the axis refuses was taken")
        except ModbusExceptionReply as e:
            assert e.code == 3
    assert api.get("%MF328")["%MF328"] == 7000.0


# every text of each shown rung's svg: its box, and the right rail's x and top (the
# rightmost vertical line); the title above the rails is left out of the rail check
LADDER_GEOMETRY = """() => [...document.querySelectorAll('#ladder div[data-rung] svg')]
.map((svg) => {
  const at = (l, a) => +l.getAttribute(a);
  const v = [...svg.querySelectorAll('line')].filter((l) => at(l, 'x1') === at(l, 'x2'));
  const rail = v.reduce((a, l) => (at(l, 'x1') > at(a, 'x1') ? l : a), v[0]);
  return { rung: svg.closest('[data-rung]').dataset.rung,
    rail: [at(rail, 'x1'), Math.min(at(rail, 'y1'), at(rail, 'y2'))],
    texts: [...svg.querySelectorAll('text')].map((t) => { const b = t.getBBox();
      return [t.textContent, b.x, b.y, b.width, b.height]; }) };
})"""


def _overlap(a: list, b: list, tol: float = 1.0) -> bool:
    return (a[1] + tol < b[1] + b[3] and b[1] + tol < a[1] + a[3]
            and a[2] + tol < b[2] + b[4] and b[2] + tol < a[2] + a[4])


def test_ladder_draws_short_form_timers_as_boxes_and_no_text_overlaps(module_page, tmp_path,
                                                                        daemons):
    """The drawing table's ladder (issue 33): `IN %TM0` is the timer's box (pin IN, the
    type and base and the live values inside it), no value runs into another text nor
    under the right rail, no two texts of a rung overlap, and the IL listing fits a
    1400 px window beside the ladder."""
    from softplc.il.parser import parse

    rungs = len(parse((PROGRAMS / "drawing_table.il").read_text()).rungs)
    d, url, api = start(daemons, tmp_path, "drawing_table")
    page = open_page(module_page, url)
    page.click("#tabs button[data-tab=ladder]")
    page.select_option("#ladder-zoom", "1")
    seen: set[str] = set()
    for first in range(0, rungs, 4):  # the page shows 4 rungs from the one chosen
        page.click(f"#rung-list li[data-rung='{first}']")
        sync_api.expect(page.locator(f'#ladder div[data-rung="{first}"] svg')).to_be_visible()
        for rung in page.evaluate(LADDER_GEOMETRY):
            seen.add(rung["rung"])
            texts = rung["texts"]
            for i, a in enumerate(texts):
                for b in texts[i + 1:]:
                    assert not _overlap(a, b), (rung["rung"], a, b)
            x, top = rung["rail"]
            for t in texts:
                if t[2] + t[4] > top:  # below the title
                    assert not t[1] < x < t[1] + t[3], (rung["rung"], t)
    assert len(seen) == rungs
    page.click("#rung-list li[data-rung='1']")
    svg = page.locator('#ladder div[data-rung="1"] svg')
    sync_api.expect(svg.locator("text", has_text="TON 1ms")).to_be_visible()
    texts = svg.locator("text").evaluate_all("els => els.map((e) => e.textContent)")
    assert "%TM0" in texts and "IN" in texts and "Q" in texts
    assert not any("[%TM0 IN]" in t for t in texts)
    sync_api.expect(svg.locator("text", has_text=re.compile(r"^P=2 V=\d+$"))).to_be_visible()
    page.select_option("#ladder-zoom", "1.4")  # the default zoom: a wide rung scrolls
    page.click("#rung-list li[data-rung='8']")
    sync_api.expect(page.locator('#ladder div[data-rung="8"] svg')).to_be_visible()
    listing = page.locator("#il-listing").bounding_box()
    assert listing["x"] + listing["width"] <= 1400 and listing["width"] > 300
    sync_api.expect(page.locator("#il-listing .ln.hit").first).to_be_in_viewport()
    shot(page, "ladder-drawing-table")
