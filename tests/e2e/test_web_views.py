"""The Machine tab's views of the servo table, the cutting table and the machining centre,
trends with bits and words of very different ranges, and the header when the daemon stops,
in headless Chromium (the set-up of test_web_browser.py). Screenshots go to out/."""

from __future__ import annotations

import re
import signal
import time

from daemon_util import started
from test_web_browser import PROGRAMS, browser, open_page, shot, start, sync_api, web_url

__all__ = ["browser"]  # the fixture, shared


def machine_tab(page) -> None:
    page.click("#tabs button[data-tab=machine]")


def test_servo_table_view_follows_homing(browser, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "servo_table", "--speed", "2")
    page = open_page(browser, url)
    machine_tab(page)
    sync_api.expect(page.locator("#carriage")).to_be_visible()
    assert "X = -19.531 mm" in page.locator("#machine-hint").inner_text()  # -8000 counts
    api.set("%I0.1", 1)  # start: the contactor closes, the loops close
    api.set("%I0.1", 0)
    api.set("%MW100", 2)  # home X then Y: the axes move, the FE moves
    page.wait_for_function(
        "() => /X = 0\\.0\\d\\d mm/.test(document.querySelector('#machine-hint')"
        ".textContent)", timeout=20000)
    fe = page.locator('#fe-chart polyline.fe-line[data-axis="X"]')
    pts = [tuple(map(float, p.split(","))) for p in fe.get_attribute("points").split()]
    assert len({y for _, y in pts}) > 3  # the FE of the homing move is not flat
    assert page.locator("#axes-trail").count() == 1
    shot(page, "machine-servo")
    page.close()


def test_cutting_table_view_draws_the_cut_and_the_torch(browser, tmp_path, daemons):
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
    page = open_page(browser, web_url(d))
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    machine_tab(page)
    sync_api.expect(page.locator("#tool")).to_be_visible()
    piece = load_piece(PROGRAMS / "pieces" / "cuadrado.toml", speed=10.0, move_speed=10.0)
    with CutClient("127.0.0.1", d.port, progress=None, poll_interval=0.01) as client:
        res = client.stream(piece)
    assert res.done == len(piece.segments())
    page.wait_for_function(
        "() => { const p = document.querySelector('#pen-path');"
        " return p && p.getTotalLength() > 80; }", timeout=20000)
    box = page.locator("#pen-path").bounding_box()  # the 15 mm square: about 25 px
    assert 20 < box["width"] < 40 and abs(box["width"] - box["height"]) < 2, box
    assert page.locator("#travel-path").count() == 1  # homing and the move to the start
    assert errors == []  # (a machine message without devices threw in machineHistory)
    assert "torch off" in page.locator("#machine-hint").inner_text()  # the cut is over
    shot(page, "machine-cutting")
    page.close()


def test_machining_centre_view_shows_axis_step_and_estimate(browser, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "mass_tuning", "--speed", "4")
    page = open_page(browser, url)
    machine_tab(page)
    step = page.locator("#machine-step")
    sync_api.expect(step).to_have_text(re.compile(r"^step 0 \(initial\)"))
    assert "no estimate yet" in page.locator("#machine-estimate").inner_text()
    api.set("%M205", 1)  # automatic mode from the HMI, then the softkey
    api.set("%M200", 1)
    sync_api.expect(step).to_have_text(re.compile(r"^step [12]:"), timeout=5000)
    # the axis runs to Q26 (-480 mm): the carriage moves left on the travel
    page.wait_for_function(
        "() => { const m = /X = (-?[\\d.]+) mm/.exec(document.querySelector("
        "'#table-view').textContent); return m && +m[1] < -20; }", timeout=20000)
    # the host's answer, as softplc tune writes it: mass, uncertainty, row, then EST_ACK
    api.request("write", {"writes": [{"object": "%MF406", "value": 22650.5},
                                     {"object": "%MF408", "value": 310.0},
                                     {"object": "%MW404", "value": 3},
                                     {"object": "%MW402", "value": 1}]})
    est = page.locator("#machine-estimate")
    sync_api.expect(est).to_contain_text("22650.5 kg", timeout=5000)
    assert "± 310.0 kg" in est.inner_text()
    shot(page, "machine-centre")
    page.close()


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


def test_trends_give_bits_lanes_and_words_their_own_axes(browser, tmp_path, daemons):
    d, url, api = start(daemons, tmp_path, "star_delta")
    page = open_page(browser, url)
    page.click("#tabs button[data-tab=trends]")
    first = {"%MD100": -500000, "%MW120": 3, "%M100": 1}
    for n, (pos, step, bit) in enumerate(((-500000, 3, 1), (480000, 27, 0),
                                          (-500000, 12, 1))):
        api.request("write", {"writes": [{"object": "%MD100", "value": pos},
                                         {"object": "%MW120", "value": step},
                                         {"object": "%M100", "value": bit}]})
        if n == 0:  # trend from the first values on: under load the page could
            # otherwise sample the zeros before the first write reached the PLC
            deadline = time.monotonic() + 10
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
    page.close()


def test_header_says_disconnected_and_reconnects(browser, tmp_path, daemons):
    d, url, _ = start(daemons, tmp_path, "star_delta")
    port = re.search(r":(\d+)/$", url)[1]
    page = open_page(browser, url)
    state = page.locator("#state")
    sync_api.expect(state).to_have_text("RUN")
    # a daemon that hangs (SIGSTOP): the socket stays open but nothing comes
    d.proc.send_signal(signal.SIGSTOP)
    try:
        sync_api.expect(state).to_have_text("DISCONNECTED", timeout=8000)
    finally:
        d.proc.send_signal(signal.SIGCONT)
    sync_api.expect(state).to_have_text("RUN", timeout=5000)  # updates again: live
    d.stop()  # Ctrl-C: the daemon ends, its websocket closes
    sync_api.expect(state).to_have_text("DISCONNECTED", timeout=5000)
    assert "disconnected" in page.locator("body").get_attribute("class")
    colour = "e => getComputedStyle(e).backgroundColor"
    assert state.evaluate(colour) == "rgb(90, 101, 112)"  # grey, not RUN's green
    shot(page, "disconnected")
    # the daemon comes back on the same port: the page reconnects by itself
    started(daemons, tmp_path, "--config", str(PROGRAMS / "star_delta.toml"), "--web", port,
            "--stats-interval", "0", program=PROGRAMS / "star_delta.il")
    sync_api.expect(state).to_have_text("RUN", timeout=10000)
    assert state.evaluate(colour) != "rgb(90, 101, 112)"
    assert "disconnected" not in (page.locator("body").get_attribute("class") or "")
    page.close()
