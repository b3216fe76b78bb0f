"""The Machine tab's views of the servo table, the cutting table and the machining centre,
trends with bits and words of very different ranges, and the header when the daemon stops,
in headless Chromium (the set-up of test_web_browser.py). Screenshots go to out/."""

from __future__ import annotations

import re

from daemon_util import Daemon
from test_web_browser import PROGRAMS, browser, open_page, shot, sync_api, web_url

from softplc.commands.io import Client

__all__ = ["browser"]  # the fixture, shared


def start(tmp_path, name: str, *args: str) -> tuple[Daemon, str, Client]:
    d = Daemon(tmp_path, "--config", str(PROGRAMS / f"{name}.toml"), "--web", "0",
               "--stats-interval", "0", *args, program=PROGRAMS / f"{name}.il")
    url = web_url(d)
    return d, url, Client("127.0.0.1", int(re.search(r":(\d+)/$", url)[1]))


def machine_tab(page) -> None:
    page.click("#tabs button[data-tab=machine]")


def test_servo_table_view_follows_homing(browser, tmp_path):
    d, url, api = start(tmp_path, "servo_table", "--speed", "2")
    try:
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
    finally:
        d.kill()
