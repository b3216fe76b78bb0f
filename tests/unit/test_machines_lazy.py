"""The machine packages' lazy exports (softplc/machines/lazy.py): every name resolves to
what its submodule defines, and none is shadowed by a submodule of the same name (once
imported, a submodule replaces the package attribute: `preview` was the module)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

from softplc.machines import MACHINES

PACKAGES = [*MACHINES, "gcode"]


@pytest.mark.parametrize("name", PACKAGES)
def test_no_export_is_named_like_a_submodule(name):
    pkg = importlib.import_module(f"softplc.machines.{name}")
    subs = {m.name for m in pkgutil.iter_modules(pkg.__path__)}
    assert set(getattr(pkg, "_EXPORTS", {})) & subs == set()


@pytest.mark.parametrize("name", PACKAGES)
def test_every_export_is_its_submodules_object(name):
    pkg = importlib.import_module(f"softplc.machines.{name}")
    for export, sub in getattr(pkg, "_EXPORTS", {}).items():
        module = importlib.import_module(f"softplc.machines.{name}.{sub}")
        assert getattr(pkg, export) is getattr(module, export)
