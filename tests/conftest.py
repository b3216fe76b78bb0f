"""Fixtures shared by several test modules, and the test tiers (tests/tiers.py)."""

import gc
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from chromium import browser, chromium  # noqa: F401 (fixtures: one browser per worker)
from daemon_util import daemons, kill_all  # noqa: F401 (the `daemons` fixture)
from tiers import TIERS, tier_of

# Test modules import each other's helpers across tiers (an e2e web test the unit tier's
# program generator): every tier folder is importable whichever tier runs.
for _tier in TIERS:
    sys.path.insert(0, str(Path(__file__).resolve().parent / _tier))

# The tests start about 60 daemons and `softplc` commands as subprocesses: with
# PYTHONDONTWRITEBYTECODE=1 in the environment each of them would compile every softplc
# module from source again (about 0.5 s of CPU per start); with it unset the first one
# writes the __pycache__ (git-ignored) and the others load it.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


# The collector's thresholds in a test worker (Python's default: 700, 10, 10). The tests
# allocate far more short-lived objects than a program run does (ASTs, z3 terms, hypothesis
# examples): at the default, the collector took 12 % of the unit tier's CPU (8.9 of 74
# CPU-s, measured with gc.callbacks); with what collection imported frozen and these, 4.
GC_THRESHOLDS = (10_000, 10, 10)


def pytest_collection_finish(session: pytest.Session) -> None:
    """What the collection imported (softplc, numpy, lark, z3, the test modules) lives until
    the worker ends: out of the collector's walks, as the daemon does with its program."""
    gc.collect()
    gc.freeze()
    gc.set_threshold(*GC_THRESHOLDS)


def pytest_sessionfinish(session: pytest.Session) -> None:
    """No daemon outlives the suite, whichever test failed before stopping its own."""
    kill_all()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test with its folder's tier (`-m unit`, `-m "not e2e"`, ...)."""
    for item in items:
        path = Path(str(item.path))
        tier = tier_of(path)
        fixtures = getattr(item, "fixturenames", ())
        if "daemons" in fixtures and tier != "e2e":
            raise pytest.UsageError(f"{item.nodeid} uses the daemons fixture: it belongs in "
                                    "tests/e2e")
        if "chromium" in fixtures and not path.name.endswith(BROWSER_MODULE_SUFFIX):
            raise pytest.UsageError(f"{item.nodeid} uses the browser: its module's name must "
                                    f"end in {BROWSER_MODULE_SUFFIX} (they share one worker)")
        item.add_marker(getattr(pytest.mark, tier))


# Under `--dist loadfile` each module is one unit of work; the modules that drive Chromium
# (named *_browser.py, checked above) are one unit together, so that one worker starts a
# browser instead of each (a Chromium costs seconds of CPU to start and to keep).
BROWSER_MODULE_SUFFIX = "_browser.py"
BROWSER_SCOPE = "tests/e2e/*" + BROWSER_MODULE_SUFFIX


@pytest.hookimpl(optionalhook=True)  # xdist's hook: absent under -p no:xdist
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    if config.getoption("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class BrowserModulesTogether(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = super()._split_scope(nodeid)
            return BROWSER_SCOPE if path.endswith(BROWSER_MODULE_SUFFIX) else path

    return BrowserModulesTogether(config, log)


class TierViolation(AssertionError):
    """A unit test reached for the network or a process: it belongs to a higher tier."""


@pytest.fixture(autouse=True)
def _unit_tier_guard(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch):
    """Unit tests run without sockets or subprocesses (tests/tiers.py)."""
    if request.node.get_closest_marker("unit") is None:
        yield
        return

    def refuse(*_a, **_k):
        raise TierViolation(f"{request.node.nodeid} is marked unit but opens a socket or "
                            "starts a process: move it to tests/integration or tests/e2e")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket.socket, "bind", refuse)
    monkeypatch.setattr(subprocess.Popen, "__init__", refuse)
    yield


@pytest.fixture
def star():
    """The star-delta example on the daemon's stack in one process (test_web_api.Stack)."""
    from test_web_api import STAR, Stack  # (aiohttp and the web monitor: only when asked)

    s = Stack(STAR, STAR.with_suffix(".toml"))
    yield s
    s.close()


@pytest.fixture
def netns_serial():
    """One `plant up` of the shipped example at a time on this machine, whichever xdist
    worker runs it: two would make the same namespaces (named from the plant file's path)
    and claim the same /24 from the root namespace."""
    import fcntl
    import tempfile

    with open(Path(tempfile.gettempdir()) / "softplc-tests-netns.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield
