"""The debugger: `session.Session` runs the commands of the table in `registry.py`.

The command modules fill that table when this package is imported (here rather than in
session.py: they name `Session` in their type hints, so they sit above it).
"""

from softplc.debug import cmd_breaks, cmd_data, cmd_run, cmd_views  # noqa: F401 (they fill COMMANDS)
