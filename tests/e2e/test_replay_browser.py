"""`softplc replay --web`: a counterexample of star_delta_defect.il on the ladder in a real
browser (Debian's Chromium through Playwright, as tests/e2e/test_web_browser.py), and its
read-only API over HTTP."""

from __future__ import annotations

import json
import os
import queue
import re
import subprocess
import sys
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from test_web_browser import ROOT, shot
from waits import PAGE_POLL_MS

from softplc.cli import main

LP = ROOT / "ladder_programs"
DEFECT = [str(LP / "star_delta_defect.il"), "--config", str(LP / "star_delta.toml")]
START_TIMEOUT = 60.0  # s for the replay process's banner (two shared cores, z3 not loaded)


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """A counterexample of several scans (the delta contactor after the star time, with a
    free scan period) served by `softplc replay --web 0`: its URL and scan count."""
    d = tmp_path_factory.mktemp("replay")
    cex = d / "cex.json"
    assert main(["verify", *DEFECT, "--require-expr", "never %Q0.2", "--scan-period",
                 "10ms:1s", "--depth", "12", "-q", "--cex", str(cex)]) == 2
    total = len(json.loads(cex.read_text())["counterexamples"][0]["scans"])
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "softplc", "replay", *DEFECT, str(cex),
                             "--web", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=env)
    lines: queue.Queue[str] = queue.Queue()
    out: list[str] = []

    def pump() -> None:
        for line in proc.stdout:  # type: ignore[union-attr]
            lines.put(line)
        lines.put("")
    threading.Thread(target=pump, daemon=True).start()
    try:
        url = None
        while url is None:
            line = lines.get(timeout=START_TIMEOUT)
            assert line, "softplc replay ended: " + "".join(out)
            out.append(line)
            m = re.search(r"replay page on (http://127\.0\.0\.1:\d+/)", line)
            url = m and m[1]
        assert any("REPLAY of a counterexample" in x for x in out)  # the banner
        yield url, total
    finally:
        proc.terminate()
        proc.wait(10)


def get(url: str, **headers: str) -> tuple[int, dict]:
    req = urllib.request.Request(url, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"{}")


def test_the_api_plays_the_trace_and_takes_no_writes(served):
    url, total = served
    status, info = get(url + "api/replay")
    assert status == 200 and info["violated_at"] == info["reported"] == total
    assert info["watch"] == ["%Q0.2"] and [r["status"] for r in info["history"]][-1] == \
        "VIOLATED"
    status, frame = get(f"{url}api/replay/scan/{total}")
    assert frame["status"] == "VIOLATED" and frame["values"][0]["engine"] == 1
    assert any('class="req"' in svg for svg in frame["rungs"])
    assert get(url + "api/replay/scan/x")[0] == 400
    assert get(url + "api/replay", Host="evil.example")[0] == 403  # DNS rebinding
    post = urllib.request.Request(url + "api/replay/scan/1", data=b"{}", method="POST",
                                  headers={"Content-Type": "application/json"})
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(post, timeout=30)
    assert e.value.code == 405  # no route changes anything


def test_the_slider_shows_the_violation_on_the_ladder(served, browser):
    url, total = served
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    try:
        page.goto(url)
        page.wait_for_selector('body[data-scan="0"]')  # paused at the cold start
        assert page.locator("#status").inner_text() == "cold start"
        page.locator("#slider").fill(str(total))
        page.wait_for_selector(f'body[data-scan="{total}"]')
        assert page.locator("#status").inner_text() == "VIOLATED"
        row = page.locator("#values tbody tr").first
        assert row.locator("td").nth(0).inner_text() == "%Q0.2"
        assert row.locator("td").nth(1).inner_text() == "1"
        labels = page.locator("#rungs svg text.req")
        assert labels.count() >= 2 and set(labels.all_text_contents()) == {"%Q0.2"}
        red = labels.first.evaluate("e => getComputedStyle(e).fill")
        assert red == "rgb(176, 0, 32)"  # replay.css: the requirement's labels
        assert page.locator("#history tr.current td").first.inner_text() == str(total)
        path: Path = shot(page, "replay-violation")
        page.locator("#slider").focus()
        page.keyboard.press("ArrowLeft")  # the range input's own step: one scan back
        page.wait_for_selector(f'body[data-scan="{total - 1}"]')
        assert page.locator("#status").inner_text() == "holds"
        assert page.locator("#values tbody tr td").nth(1).inner_text() == "0"
        assert path.exists()
        page.locator("#first").click()
        page.wait_for_selector('body[data-scan="0"]')
        # play from two scans before the end (a scan is shown PLAY_MS, 0.7 s: the whole
        # trace would take seconds to show the same): it plays to the end and stops there
        assert total > 2
        page.locator("#slider").fill(str(total - 2))
        page.wait_for_selector(f'body[data-scan="{total - 2}"]')
        page.locator("#play").click()
        page.wait_for_selector(f'body[data-scan="{total}"]', timeout=60_000)
        page.wait_for_function("document.getElementById('play').textContent === 'play'",
                               polling=PAGE_POLL_MS)
        assert page.locator("#status").inner_text() == "VIOLATED"
    finally:
        page.close()
