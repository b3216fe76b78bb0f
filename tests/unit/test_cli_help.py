"""Every `softplc` subcommand's --help fits 80 columns and shows copyable examples."""

from __future__ import annotations

import argparse

import pytest

from softplc.cli import build_parser


def _subparsers(parser: argparse.ArgumentParser | None = None, prefix: str = ""
                ) -> dict[str, argparse.ArgumentParser]:
    """Every subcommand's parser, nested ones too (`symbols export`)."""
    parser = parser or build_parser()
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[prefix + name] = sub
                out.update(_subparsers(sub, f"{prefix}{name} "))
    return out


@pytest.mark.parametrize("name", sorted(_subparsers()))
def test_help_within_80_columns(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    text = _subparsers()[name].format_help()
    long = [line for line in text.splitlines() if len(line) > 80]
    assert not long, f"softplc {name} --help has lines over 80 columns: {long}"
    # argparse %-formats help strings but not descriptions or epilogs: a doubled %
    # left in one is printed as is, and a copied `%%I0.0` is a malformed address
    assert "%%" not in text


def test_top_level_help_within_80_columns(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    assert max(len(line) for line in build_parser().format_help().splitlines()) <= 80
