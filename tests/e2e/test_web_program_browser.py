"""The web monitor's program pages in a real browser (issue 24): the online change upload
(errors shown, losses confirmed, a counter kept), the IL listing and version, the Modbus
map page and symbols in an animation table. Same set-up as test_web_browser.py."""

from __future__ import annotations

import re

from test_web_api import Stack
from test_web_browser import (
    _module_page,  # noqa: F401 (the module_page fixture)
    open_page,
    shot,
    sync_api,
)
from test_web_program import NO_COUNTER, NO_COUNTER_CONFIG, SOURCE, STEADY


def url(s: Stack) -> str:
    return f"http://127.0.0.1:{s.port}/"


def set_counter(s: Stack, n: int) -> None:
    with s.lock:
        c = s.plc.mem.blocks["C"][0]
        c.set_state(c.state() | {"V": n})
    s.scans()


def load(page, program: str, config: str = "") -> None:
    page.fill("#prog-text", program)
    page.fill("#prog-config", config)
    page.click("#prog-load")


def test_upload_errors_losses_and_a_kept_counter(module_page, star, tmp_path):
    set_counter(star, 6)
    page = open_page(module_page, url(star))
    sync_api.expect(page.locator("#version")).to_contain_text("v0 · ")
    page.click("#tabs button[data-tab=program]")
    sync_api.expect(page.locator("#prog-listing .ln")).to_have_count(
        len(SOURCE.split("\n")))
    # errors: every one with its line, nothing changed
    load(page, SOURCE.replace("ST    %Q0.1", "STT   %Q0.1"))
    result = page.locator("#prog-result")
    sync_api.expect(result).to_have_class(re.compile(r"\bbad\b"))
    bad_line = next(n for n, t in enumerate(SOURCE.splitlines(), 1) if t == "ST    %Q0.1")
    sync_api.expect(result).to_contain_text(f"line {bad_line}:1")
    assert star.plc.program_version == 0
    result.locator("li.err").first.click()  # the line is selected in the program text
    selected = page.evaluate("() => { const a = document.querySelector('#prog-text');"
                             " return a.value.slice(a.selectionStart, a.selectionEnd); }")
    assert selected == "STT   %Q0.1"
    shot(page, "program-errors")
    # no loss, from a file: loaded at once, the counter kept, version and listing updated
    steady = tmp_path / "steady.il"
    steady.write_text(STEADY)
    page.set_input_files("#prog-file", str(steady))
    sync_api.expect(page.locator("#prog-text")).to_have_value(STEADY)
    page.fill("#prog-config", "")
    page.click("#prog-load")
    sync_api.expect(result).to_have_class(re.compile(r"\bok\b"))
    sync_api.expect(page.locator("#version")).to_contain_text("v1 · ")
    assert page.locator("#version").get_attribute("title").startswith("steady.il")
    assert star.plc.program_version == 1 and star.plc["%C0.V"] == 6
    sync_api.expect(page.locator("#prog-listing .ln")).to_have_count(
        len(STEADY.split("\n")))
    # a loss: listed, then confirmed
    load(page, NO_COUNTER, NO_COUNTER_CONFIG)
    sync_api.expect(result).to_have_class(re.compile(r"\bwarn\b"))
    sync_api.expect(result).to_contain_text("%C0 is no longer used")
    assert star.plc.program_version == 1
    shot(page, "program-losses")
    page.click("#prog-confirm")
    sync_api.expect(result).to_have_class(re.compile(r"\bok\b"))
    sync_api.expect(page.locator("#version")).to_contain_text("v2 · ")
    assert star.plc.program_version == 2 and 0 not in star.plc.mem.blocks["C"]
    # the ladder tab: the listing beside the live ladder, the shown rung's lines marked
    page.click("#tabs button[data-tab=ladder]")
    page.click("#rung-list li[data-rung='3']")
    hit = page.locator("#il-listing .ln.hit")
    sync_api.expect(hit.first).to_contain_text("BLK   %TM0")
    assert "END_BLK" in hit.last.inner_text()
    sync_api.expect(page.locator('#ladder div[data-rung="3"] svg')).to_be_visible()
    shot(page, "ladder-listing")


def test_modbus_map_page(module_page, star):
    page = open_page(module_page, url(star))
    page.click("#tabs button[data-tab=map]")
    row = page.locator('#map-tags tr[data-address="%MW10"]')
    sync_api.expect(row).to_be_visible()
    assert row.locator("td.symbol").inner_text() == "STARTS"
    assert row.locator("td.reference").inner_text() == "40011"
    assert row.get_attribute("title") == "number of starts"
    hidden = page.locator('#map-hidden tr[data-address="%Q0.1"]')
    sync_api.expect(hidden).to_contain_text("KM2_STAR")
    sync_api.expect(page.locator("#map-note")).to_contain_text("not on the map")
    with page.expect_download() as dl:
        page.click("#map-csv")
    text = open(dl.value.path(), encoding="utf-8").read()
    assert text.startswith("tag,address,type") and "STARTS,%MW10," in text
    shot(page, "modbus-map")


def test_symbols_in_an_animation_table(module_page, star):
    page = open_page(module_page, url(star))  # (no table kept: open_page clears them)
    page.click("#tabs button[data-tab=tables]")
    page.fill("#table-add", "starts, star_time.p, %MW11")  # symbols typed, any case
    page.click("#table-add-btn")
    row = page.locator('#anim tr[data-obj="%MW10"]')
    sym = row.locator(".sym")
    sync_api.expect(sym).to_have_text("STARTS")
    assert sym.get_attribute("title") == "number of starts"
    sync_api.expect(page.locator('#anim tr[data-obj="%TM0.P"] .val')).to_have_text("50")
    sync_api.expect(page.locator('#anim tr[data-obj="%TM0.P"] .sym')).to_have_text(
        "STAR_TIME.P")
    sync_api.expect(page.locator('#anim tr[data-obj="%MW11"] .sym')).to_have_text("STATE")
    preset = page.locator('#anim tr[data-obj="%TM0.P"]')  # written through its row
    preset.locator("input.w").fill("30")
    preset.locator("button.write").click()
    sync_api.expect(preset.locator(".val")).to_have_text("30")
    assert star.plc["%TM0.P"] == 30
    shot(page, "symbols-table")
