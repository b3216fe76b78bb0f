"""The plant page of `plant up --netns` in a real browser (issue 35, 6; softplc.commands.
plantweb): the three controllers of the example line, their states, and a monitor link
that opens the controller's own web monitor (on its own address, through the veth `plant
up` made from this machine into the plant network) showing its program. Same browser
set-up as test_web_browser.py; skipped where network namespaces cannot be made."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_web_browser import shot, sync_api
from waits import WAIT_MS

from softplc.plant import hosts

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "ladder_programs" / "plant" / "plant.toml"
WHY = hosts.netns_works()
pytestmark = [pytest.mark.skipif(bool(WHY), reason=f"network namespaces: {WHY}"),
              pytest.mark.usefixtures("netns_serial")]


def _softplc(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "softplc", *args], env=env,
                          capture_output=True, text=True, timeout=120)


def test_the_plant_page_lists_the_controllers_and_opens_their_monitors(browser, tmp_path):
    state = tmp_path / "state"
    up = _softplc("plant", "up", str(EXAMPLE), "--netns", "--state-dir", str(state),
                  "--web", "0")
    try:
        assert up.returncode == 0, up.stderr
        record = json.loads((state / f"sp{hosts.tag(EXAMPLE)}.json").read_text())
        if not record["page"]:
            pytest.skip("this machine has an address in 10.0.35.0/24 already: no page")
        assert f"plant page: {record['page']}" in up.stdout
        page = browser.new_page(viewport={"width": 1400, "height": 600})
        page.goto(record["page"])
        rows = page.locator("#rows tr")
        sync_api.expect(rows).to_have_count(3, timeout=WAIT_MS)
        sync_api.expect(rows.locator("td:first-child")).to_have_text(
            ["master", "filler", "capper"])
        sync_api.expect(rows.locator("td:nth-child(2)")).to_have_text(
            ["RUN", "RUN", "RUN"], timeout=WAIT_MS)
        # both peers on the master's link: %SW111 = 2#11
        sync_api.expect(rows.first.locator("td:nth-child(6)")).to_have_text(
            "00000011", timeout=WAIT_MS)
        shot(page, "plant-up-page")
        link = rows.first.locator("a.monitor")
        assert link.get_attribute("href").startswith(
            f"http://{record['controllers']['master']['host']}:{hosts.WEB_PORT}/")
        with page.context.expect_page() as opened:
            link.click()
        monitor = opened.value
        monitor.wait_for_selector("#link.up", timeout=WAIT_MS)
        # the master's own program in its monitor's IL listing
        sync_api.expect(monitor.locator("#il-listing")).to_contain_text(
            "%INW1.1", timeout=WAIT_MS)
        shot(monitor, "plant-up-monitor")
    finally:
        down = _softplc("plant", "down", str(EXAMPLE), "--state-dir", str(state))
    assert down.returncode == 0, down.stderr
    assert "page: stopped" in down.stdout
