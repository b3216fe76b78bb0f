"""Debian's headless Chromium for the browser tests, launched once per test worker.

Playwright's own browser download is never used (`playwright install` is not run): the
system browser is launched by path, the headless shell when it is installed (Playwright
adds --headless). A launch costs about 3 s of CPU, so one browser lives for the worker's
session (`chromium`) and every browser test module opens its pages in it
(`browser`, registered by tests/conftest.py); at a module's end its pages are closed,
so that none goes on polling a daemon that has stopped.
"""

from __future__ import annotations

import functools
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

# Debian's chromium-headless-shell first: the "old" headless browser (Blink and the same
# renderer, without the full browser's UI layer), what Playwright itself runs for headless
# Chromium (https://playwright.dev/docs/browsers#chromium-headless-shell). Measured on the
# star-delta monitor: a new page with the monitor loaded costs it about 0.9 s of CPU, the
# full browser 2.5 s (docs/decisions/browser-tests-headless-shell.md).
SHELL = "/usr/lib/chromium/chromium-headless-shell"
# The full browser by its binary, not /usr/bin/chromium: Debian's launcher adds flags for a
# desktop user (--enable-gpu-rasterization: rasterising in the GPU process's SwiftShader).
FULL = "/usr/lib/chromium/chromium"
CHROMIUM = next((p for p in (SHELL, FULL) if Path(p).exists()),
                shutil.which("chromium"))
MISSING = "chromium is not installed (Debian package `chromium`; `make sysdeps` as root)"
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
# the full browser only: its new headless mode has the desktop browser's windows, and each
# page's window starts a WebUI renderer for the address bar's popup (about 1 s of CPU per
# page; Puppeteer turns these off too: puppeteer/puppeteer#15278)
FULL_ARGS = ["--disable-features=WebUIOmniboxPopup,WebUIOmniboxAimPopup"]


PLAYWRIGHT_MISSING = "playwright is not installed (the test extra)"


@functools.cache
def _playwright() -> Any:
    """`playwright.sync_api`, imported once, `expect` waiting as long as a hang takes (its
    own default, 5 s, ran out under load)."""
    from waits import WAIT_MS

    api = pytest.importorskip("playwright.sync_api", reason=PLAYWRIGHT_MISSING)
    api.expect.set_options(timeout=WAIT_MS)
    return api


class _SyncApi:
    """`playwright.sync_api`, imported at its first use: the browser modules run on one
    worker (tests/conftest.py), and the others collect them without importing playwright
    (0.1-0.2 CPU-s each)."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):  # pytest's collection probes a module's names for markers
            raise AttributeError(name)
        return getattr(_playwright(), name)


sync_api: Any = _SyncApi()


@pytest.fixture(scope="session")
def chromium() -> Iterator[Any]:
    if CHROMIUM is None:
        pytest.skip(MISSING)
    with sync_api.sync_playwright() as p:
        shell = Path(CHROMIUM).name == Path(SHELL).name
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS + ([] if shell else FULL_ARGS))
        yield b
        b.close()


@pytest.fixture(scope="module")
def browser(chromium: Any) -> Iterator[Any]:
    """The worker's browser for one module: `browser.new_page(...)`; its pages closed at
    the module's end (each page is a context of its own)."""
    yield chromium
    for context in list(chromium.contexts):
        context.close()
