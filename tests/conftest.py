"""Fixtures shared by several test modules."""

from daemon_util import daemons  # noqa: F401 (the `daemons` fixture)
