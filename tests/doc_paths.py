"""Paths into a parsed TOML document, for the fuzzers that mutate one (configurations,
plant files)."""

from __future__ import annotations

from typing import Any

KeyPath = tuple[Any, ...]


def key_paths(node: Any, prefix: KeyPath = ()) -> list[KeyPath]:
    """Every key path and list index in a parsed TOML document."""
    out = []
    items = node.items() if isinstance(node, dict) else (
        enumerate(node) if isinstance(node, list) else ())
    for k, v in items:
        out.append(prefix + (k,))
        out += key_paths(v, prefix + (k,))
    return out


def at(node: Any, path: KeyPath) -> Any:
    """The value at `path` (KeyError, IndexError or TypeError where an earlier mutation
    replaced or removed part of it)."""
    for k in path:
        node = node[k]
    return node
