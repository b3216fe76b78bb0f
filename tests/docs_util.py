"""The documentation's text for the tests that run its examples: README.md and the pages of
the site (docs/**/*.md), so that no example can drift from the code."""

from __future__ import annotations

import functools
import re
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def page(name: str) -> str:
    """One page by its path from the repository root (`README.md`, `docs/pytest.md`)."""
    return (ROOT / name).read_text(encoding="utf-8")


@functools.cache
def pages() -> Mapping[str, str]:
    """Every documentation page: path from the repository root -> text (read once per
    process: the tests' parameters ask for the pages' blocks in several languages)."""
    paths = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    return MappingProxyType({str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
                             for p in paths})


def fenced(text: str, after: str, lang: str) -> str:
    """The first ```lang block after the heading or sentence `after`."""
    start = text.index(after)
    m = re.compile(rf"^```{lang}\n(.*?)^```", re.S | re.M).search(text, start)
    assert m, f"no {lang} block after {after!r}"
    return m.group(1)


def blocks(lang: str) -> list[tuple[str, int, str]]:
    """Every ```lang block of every page: (page, line of the fence, text)."""
    return [(name, line, text) for name, line, fence_lang, text in _fences()
            if fence_lang == lang]


@functools.cache
def _fences() -> tuple[tuple[str, int, str, str], ...]:
    """Every fenced block of every page: (page, line of the fence, language, text)."""
    return tuple((name, text.count("\n", 0, m.start()) + 1, m.group(1), m.group(2))
                 for name, text in pages().items() for m in FENCE.finditer(text))
