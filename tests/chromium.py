"""Debian's headless Chromium for the browser tests, launched once per test worker.

Playwright's own browser download is never used (`playwright install` is not run): the
system browser is launched by path. A launch costs about 3 s of CPU, so one browser lives
for the worker's session (`chromium`) and every browser test module opens its pages in it
(`browser`, registered by tests/conftest.py); at a module's end its pages are closed, so
that none goes on polling a daemon that has stopped.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium"
                                        if Path("/usr/bin/chromium").exists() else None)
MISSING = "chromium is not installed (Debian package `chromium`; `make sysdeps` as root)"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="session")
def chromium() -> Iterator[Any]:
    if CHROMIUM is None:
        pytest.skip(MISSING)
    sync_api = pytest.importorskip("playwright.sync_api",
                                   reason="playwright is not installed (the test extra)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def browser(chromium: Any) -> Iterator[Any]:
    """The worker's browser for one module: `browser.new_page(...)`; its pages closed at
    the module's end (each page is a context of its own)."""
    yield chromium
    for context in list(chromium.contexts):
        context.close()
