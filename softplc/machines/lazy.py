"""Lazy package exports (PEP 562): a machine package names its API at the top
(`from softplc.machines.cutting import load_piece`) without importing it, so that `softplc
--help`, which registers every machine's command, imports none of their libraries."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, exports: dict[str, str]) -> tuple[Callable[[str], Any],
                                                                    Callable[[], list[str]]]:
    """`__getattr__` and `__dir__` for `package`: each name of `exports` is imported from
    its submodule (`{"load_piece": "load"}`) on first use. A name must not be a submodule's
    own name: once that submodule is imported the package attribute is the module, and
    `__getattr__` is no longer asked (tests/unit/test_machines_lazy.py checks it)."""

    def getattr_(name: str) -> Any:
        sub = exports.get(name)
        if sub is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{sub}"), name)

    def dir_() -> list[str]:
        return sorted(exports)

    return getattr_, dir_
