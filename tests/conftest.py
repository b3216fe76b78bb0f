"""Fixtures shared by several test modules."""

import os

from daemon_util import daemons  # noqa: F401 (the `daemons` fixture)

# The tests start about 60 daemons and `softplc` commands as subprocesses: with
# PYTHONDONTWRITEBYTECODE=1 in the environment each of them would compile every softplc
# module from source again (about 0.5 s of CPU per start); with it unset the first one
# writes the __pycache__ (git-ignored) and the others load it.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
