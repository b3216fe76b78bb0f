"""The shipped example machines (`ladder_programs/` of the source tree): where a command's
default program or machine configuration is found whatever the current folder."""

from __future__ import annotations

from pathlib import Path

#: The shipped programs and machine configurations, beside the package in the source tree.
EXAMPLES = Path(__file__).resolve().parents[2] / "ladder_programs"


def example(name: str) -> Path:
    """The shipped file `name` (e.g. "cutting_table.toml"), by absolute path."""
    return EXAMPLES / name
