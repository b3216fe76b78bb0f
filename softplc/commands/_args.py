"""Argument types shared by the subcommands."""

from __future__ import annotations

import argparse
from collections.abc import Callable


def size_arg(what: str, unit: str, example: str) -> Callable[[str], tuple[float, float]]:
    """An argparse type for `WxH` sizes ("25x25", or "25" for a square)."""

    def parse(text: str) -> tuple[float, float]:
        try:
            w, _, h = text.lower().partition("x")
            return float(w), float(h or w)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} {text!r}: expected WxH in {unit}, "
                                             f"e.g. {example}") from None

    return parse
