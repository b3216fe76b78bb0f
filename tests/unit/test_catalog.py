"""The catalog of object families (softplc/twido/catalog.py): every entry's references resolve,
and the layers that read it (address syntax, bindings, profile, configuration schema,
block set-up) agree with it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from pydantic import BaseModel

from softplc import PLC
from softplc.config import Config
from softplc.errors import ConfigError, ProgramError
from softplc.program import Names
from softplc.twido import catalog
from softplc.twido.address import BLOCK_FIELDS, parse_address
from softplc.twido.profile import DEFAULT_PROFILE

FAMILIES = list(catalog.FAMILIES.values())
IDS = [f.kind for f in FAMILIES]


@pytest.mark.parametrize("fam", FAMILIES, ids=IDS)
def test_every_reference_of_an_entry_resolves(fam):
    cls = fam.block_class
    assert isinstance(cls, type) and fam.pins == tuple(getattr(cls, "PINS", ()))
    if fam.model:
        assert issubclass(fam.config_model(), BaseModel)
    for hook in (fam.setup, fam.finish, fam.default):
        if hook:
            assert callable(catalog.resolve(hook))
    assert bool(fam.section) == bool(fam.setup)  # a configured family is set up
    assert not (fam.unconfigured and fam.default)  # a hint or a default, not both


@pytest.mark.parametrize("fam", [f for f in FAMILIES if f.addressable], ids=lambda f: f.kind)
def test_the_address_syntax_is_the_catalogs(fam):
    assert BLOCK_FIELDS[fam.kind] == dict(fam.fields)
    ref = parse_address(f"%{fam.kind}1")
    assert ref.kind == fam.kind and ref.is_block
    for name, (typ, writable) in fam.fields.items():
        r = parse_address(f"%{fam.kind}1.{name}")
        assert (r.field, r.type, r.writable) == (name, typ, writable)
    if fam.bits:  # %SBRi.j, j < bits
        assert parse_address(f"%{fam.kind}0.{fam.bits - 1}").bit == fam.bits - 1


@pytest.mark.parametrize("fam", FAMILIES, ids=IDS)
def test_counts_bindings_and_sections_come_from_the_entry(fam):
    assert DEFAULT_PROFILE.count(fam.kind) == fam.count
    assert Names.is_bound(Names.block(fam.kind, fam.count - 1))
    if fam.section:
        assert fam.section in Config.model_fields


def test_the_block_sections_are_typed_and_report_every_problem_at_once():
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.5\n", {
            "pid": {"0": {"measure": "%MW0", "setpoint": 5, "kpp": 1}},
            "pls": {"%PLS0": {"base": "2ms"}},
            "very_fast_counters": {"%VFC0": {"s0": 70000}},
        })
    lines = str(e.value).splitlines()
    assert any(x.startswith("pid.0.kpp: unknown key; known: action") for x in lines)
    assert any(x.startswith('pls."%PLS0".base: expected') for x in lines)
    assert any(x.startswith('very_fast_counters."%VFC0".s0:') for x in lines)


def test_an_unknown_key_names_the_families_fields():
    with pytest.raises(ConfigError, match=r'fast_counters\."%FC0"\.mod: unknown key; '
                                          r'known: mode, preset'):
        PLC.from_source("LD 1\nST %Q0.5\n", {"fast_counters": {"%FC0": {"mod": "up"}}})


@pytest.mark.parametrize("fam", [f for f in FAMILIES if f.unconfigured], ids=lambda f: f.kind)
def test_an_unconfigured_block_gets_its_entrys_hint(fam):
    bits = [f for f, (t, _) in fam.fields.items() if t == "bool"]
    src = (f"LD %{fam.kind}0.{bits[0]}\nST %M0\n" if bits else
           f"LD 1\n[ %MW0 := %{fam.kind}0.{next(iter(fam.fields))} ]\n")
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src)
    assert f"%{fam.kind}0 is used but not configured" in str(e.value)
    assert fam.section in str(e.value)


def test_a_default_block_is_created_for_the_program():
    plc = PLC.from_source("LD 1\nI %R0\nCU %C3\n")
    assert plc.mem.blocks["R"][0].depth == DEFAULT_PROFILE.count("FIFO_DEPTH")
    assert plc.mem.blocks["C"][3].P == 9999  # the class's own default preset


def test_the_catalog_imports_nothing_of_softplc():
    """It is the bottom of the package (address.py reads it): what it names above itself is
    a "module:attribute" string."""
    tree = ast.parse(Path(catalog.__file__).read_text())
    imported = [n.module or "." for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    imported += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert not [m for m in imported if m.startswith(("softplc", "."))], imported
    assert all(m in ("__future__", "importlib", "collections.abc", "dataclasses", "functools",
                     "typing") for m in imported), imported
