"""Subcommands of the `softplc` command (see softplc/cli.py)."""
