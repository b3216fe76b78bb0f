"""The device catalog (softplc/devices/base.py `DEVICE_MODULES`, and the machines' in
softplc/machines/devices.py): every `register_device("NAME")` in the sources is listed
with the module it is in, and nothing else; a lookup imports the module and gives the
class it registered; the names alone import nothing."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import softplc
from softplc.devices.base import DEVICE_MODULES, DeviceTypes, device_types
from softplc.machines.devices import DEVICE_MODULES as MACHINE_DEVICE_MODULES

PACKAGE = Path(softplc.__file__).parent


def registered_in_sources() -> dict[str, str]:
    """{type name: module} of every `@register_device("NAME")` decorator under softplc/."""
    found: dict[str, str] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text()
        if "register_device(" not in text:  # parsing all 250 modules: 1.5 CPU-s
            continue
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == \
                    "register_device" and node.args:
                name = node.args[0]
                assert isinstance(name, ast.Constant), f"{module}: a literal type name"
                assert name.value not in found, f"{name.value} registered twice"
                found[name.value] = module
    return found


def test_the_catalog_is_what_the_modules_register():
    in_sources = registered_in_sources()
    assert {"stepper", "servo_axis", "pen", "feed_axis"} <= set(in_sources)  # the scan works
    assert dict(device_types().modules) == in_sources
    assert not DEVICE_MODULES.keys() & MACHINE_DEVICE_MODULES.keys()
    # the core lists its own, the machines theirs (the core names no machine module)
    assert all(m.startswith("softplc.devices.") for m in DEVICE_MODULES.values())
    assert all(m.startswith("softplc.machines.") for m in MACHINE_DEVICE_MODULES.values())


def test_each_lookup_gives_the_class_its_module_registered():
    for type_name, cls in device_types().items():
        assert cls.type_name == type_name
        assert cls.__module__ == device_types().modules[type_name]


def test_names_import_nothing_and_a_wrong_catalog_is_told():
    types = DeviceTypes({"ghost": "softplc.no_such_module", "wrong": "softplc.errors"})
    assert sorted(types) == ["ghost", "wrong"] and "ghost" in types and len(types) == 2
    assert types.get("nothing") is None
    with pytest.raises(ModuleNotFoundError):
        types["ghost"]
    with pytest.raises(ImportError, match="softplc.errors registers no device type 'wrong'"):
        types["wrong"]
