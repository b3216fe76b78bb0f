"""Test tiers: every test is `unit`, `integration` or `e2e`, and its folder says which
(tests/unit, tests/integration, tests/e2e; the markers are in pyproject.toml).

- e2e: crosses a process or socket boundary (daemons, `softplc` subprocesses, Modbus over
  loopback TCP, mbpoll, the browser, pexpect);
- integration: several parts in one process (a machine program with its devices, the
  debugger over a PLC, the pytest plugin run by pytester, the verifier's child processes);
- unit: the rest (one instruction family, one module).

A unit test that opens a socket or starts a process fails (the guard in conftest.py), and so
does a test outside tests/e2e that asks for the `daemons` fixture: a test cannot sit in a
tier faster than it is.
"""

from __future__ import annotations

from pathlib import Path

TIERS = ("unit", "integration", "e2e")
HERE = Path(__file__).resolve().parent


def tier_of(path: Path) -> str:
    """The tier of the test module at `path`: the tier folder it stands in."""
    rel = path.resolve().relative_to(HERE)
    if rel.parts and rel.parts[0] in TIERS:
        return rel.parts[0]
    raise ValueError(f"{path}: a test module stands in tests/unit, tests/integration or "
                     "tests/e2e (its folder is its tier)")
