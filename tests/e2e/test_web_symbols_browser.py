"""Symbols in the web monitor, in a real browser (issue 33): the Simulation tab shows each
I/O's symbol beside its address, and the ladder's find box finds rungs by the symbols of the
objects they use. The set-up (system Chromium by path, screenshots in out/) is
test_web_browser.py's."""

from __future__ import annotations

import pytest
from daemon_util import Daemon
from test_web_browser import (
    PROGRAMS,
    _module_page,  # noqa: F401 (the module_page fixture)
    open_page,
    shot,
    sync_api,
    web_url,
)


@pytest.fixture(scope="module")
def star_daemon(tmp_path_factory):
    """star_delta.il with star_delta.toml, whose symbols_file names its I/O."""
    d = Daemon(tmp_path_factory.mktemp("star-symbols"), "--config",
               str(PROGRAMS / "star_delta.toml"), "--web", "0", "--stats-interval", "0",
               program=PROGRAMS / "star_delta.il")
    yield d
    d.kill()


def test_simulation_tab_shows_the_symbols_beside_the_addresses(module_page, star_daemon):
    page = open_page(module_page, web_url(star_daemon))
    sym = page.locator('#modules .io[data-addr="%I0.0"] .iosym')
    sync_api.expect(sym).to_have_text("START_PB")
    sync_api.expect(sym).to_be_visible()  # a column, not a tooltip only
    assert sym.get_attribute("title") == "start push button (NO)"  # the comment
    sync_api.expect(page.locator('#modules .io[data-addr="%Q0.0"] .iosym')).to_have_text(
        "KM1_MAIN")
    sync_api.expect(page.locator('#modules .io[data-addr="%I0.5"] .iosym')).to_have_text("")
    path = shot(page, "symbols-simulation")
    assert path.exists()


def visible_rungs(page, text: str) -> list[int]:
    page.fill("#rung-filter", text)
    return [int(li.get_attribute("data-rung")) for li in page.locator("#rung-list li").all()
            if li.is_visible()]


def test_ladder_find_box_finds_rungs_by_the_symbols_they_use(module_page, star_daemon):
    page = open_page(module_page, web_url(star_daemon))
    page.click("#tabs button[data-tab=ladder]")
    page.wait_for_selector("#rung-list li")
    by_address = visible_rungs(page, "%m10")  # STAR_DONE = %M10 (star_delta_symbols.csv)
    by_symbol = visible_rungs(page, "star_done")
    assert len(by_address) >= 2 and by_symbol == by_address
    titles = [page.locator(f'#rung-list li[data-rung="{n}"]').inner_text() for n in by_symbol]
    assert not any("STAR_DONE" in t.upper() for t in titles)  # found by use, not by title
    assert visible_rungs(page, "KM3_DELTA") == visible_rungs(page, "%Q0.2")
    assert visible_rungs(page, "STAR_TIME") == visible_rungs(page, "%TM0")  # a block
    assert visible_rungs(page, "NO_SUCH_NAME") == []
    visible_rungs(page, "star_done")
    path = shot(page, "symbols-ladder-find")
    assert path.exists()


def test_animation_table_resolves_what_is_typed_by_the_daemons_resolver(module_page, star_daemon):
    """A symbol, a symbol's range or field typed in the table: the daemon's one resolver
    (GET /api/resolve) turns it into the address the row keeps; an unknown name is refused
    with the resolver's guess, and nothing is added."""
    page = open_page(module_page, web_url(star_daemon))
    page.click("#tabs button[data-tab=tables]")
    page.fill("#table-add", "starts:2 star_time.p")
    page.click("#table-add-btn")
    sync_api.expect(page.locator("#anim tr.group")).to_have_text("%MW10:2✕")  # the range
    for obj, name in (("%MW10", "STARTS"), ("%MW11", "STATE"), ("%TM0.P", "STAR_TIME.P")):
        sync_api.expect(page.locator(f'#anim tr[data-obj="{obj}"] .sym')).to_have_text(name)
    sync_api.expect(page.locator('#anim tr[data-obj="%TM0.P"] .val')).to_have_text("50")
    rows = page.locator("#anim tbody tr[data-obj]").count()
    page.fill("#table-add", "STATE STRATS")
    page.click("#table-add-btn")
    sync_api.expect(page.locator("#message")).to_contain_text(
        "unknown symbol 'STRATS' (did you mean STARTS?)")
    assert page.locator("#anim tbody tr[data-obj]").count() == rows  # STATE not added alone
    assert page.input_value("#table-add") == "STATE STRATS"  # kept, to be corrected
