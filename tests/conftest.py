"""Fixtures shared by several test modules, and the test tiers (tests/tiers.py)."""

import os
import socket
import subprocess
from pathlib import Path

import pytest
from daemon_util import daemons  # noqa: F401 (the `daemons` fixture)
from tiers import tier_of

# The tests start about 60 daemons and `softplc` commands as subprocesses: with
# PYTHONDONTWRITEBYTECODE=1 in the environment each of them would compile every softplc
# module from source again (about 0.5 s of CPU per start); with it unset the first one
# writes the __pycache__ (git-ignored) and the others load it.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test with its tier (`-m unit`, `-m "not e2e"`, ...)."""
    for item in items:
        function = getattr(item, "originalname", item.name)
        tier = tier_of(Path(str(item.path)).stem, function,
                       list(getattr(item, "fixturenames", ())))
        item.add_marker(getattr(pytest.mark, tier))


class TierViolation(AssertionError):
    """A unit test reached for the network or a process: it belongs to a higher tier."""


@pytest.fixture(autouse=True)
def _unit_tier_guard(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch):
    """Unit tests run without sockets or subprocesses (classify the module in tiers.py)."""
    if request.node.get_closest_marker("unit") is None:
        yield
        return

    def refuse(*_a, **_k):
        raise TierViolation(f"{request.node.nodeid} is marked unit but opens a socket or "
                            "starts a process: list its module in tests/tiers.py")

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
