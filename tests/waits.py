"""Polling waits for the end-to-end tests: a daemon, a fleet or a peer reached over a
socket changes in its own time; the timeout only bounds a failing test."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

# Generous: it bounds a failing test only (a hang), never a step of a passing one: on a
# 2-core machine shared with a busy process and parallel workers a daemon's step can
# take seconds (issue 33).
WAIT_S = 60.0
WAIT_MS = int(WAIT_S * 1000)  # the same, for Playwright
POLL_S = 0.02  # how often to look again
# how often a browser test's page.wait_for_function looks again, in the page: Playwright's
# default looks at every animation frame, which keeps the browser rendering 60 frames a
# second while it waits (about 0.06 CPU-s per s more of headless Chromium than an idle
# monitor page; every 50 ms: none measurable)
PAGE_POLL_MS = 50


def until(ok: Callable[[], Any], timeout: float = WAIT_S, period: float = POLL_S) -> None:
    """Wait until `ok()` is true; fail the test ("timed out") past `timeout`."""
    end = time.monotonic() + timeout
    while not ok():
        assert time.monotonic() < end, "timed out"
        time.sleep(period)


def until_equal(read: Callable[[], Any], want: Any, timeout: float = WAIT_S,
                period: float = POLL_S) -> Any:
    """Read until `read()` gives `want`, at most `timeout` seconds; the last value read
    (for the test's assert to show what came instead)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = read()
        if got == want:
            return got
        time.sleep(period)
    return read()
