"""Every `softplc` subcommand's --help fits 80 columns and shows copyable examples."""

from __future__ import annotations

import argparse

import pytest

from softplc.cli import build_parser


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


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
