"""The generated reference pages of the documentation site (tools/gen_docs.py) are the
code's: the committed pages equal what the code generates now, and each page covers its
source whole (every block family, configuration key, instruction keyword, function code)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import gen_docs  # noqa: E402  (tools/ is not a package)


@pytest.fixture(scope="module")
def generated() -> dict[str, str]:
    return gen_docs.generate()


def test_the_committed_pages_are_the_code_s():
    assert gen_docs.stale() == [], "run .venv/bin/python tools/gen_docs.py"


def test_a_page_that_differs_is_reported(tmp_path, generated):
    for path, text in generated.items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
    assert gen_docs.stale(tmp_path) == []
    (tmp_path / "reference/blocks.md").write_text("# Function blocks\n")
    (tmp_path / "reference/modbus-map.md").unlink()
    assert gen_docs.stale(tmp_path) == ["reference/blocks.md", "reference/modbus-map.md"]


def test_every_block_family_has_its_row(generated):
    from softplc.twido import catalog

    page = generated["reference/blocks.md"]
    for f in catalog.FAMILIES.values():
        name = f"`%{f.kind}i`" if f.addressable else f"`{f.instruction} n` (instruction)"
        assert f"| {name} | {f.title} | {f.count} |" in page


def test_every_configuration_key_is_listed(generated):
    from softplc.config import Config
    from softplc.devices.base import device_types

    page = generated["reference/configuration-keys.md"]
    for name in Config.model_fields:
        assert f"| `{name}" in page, name
    for type_name, cls in device_types().items():
        for option in getattr(getattr(cls, "Options", None), "model_fields", {}):
            assert f"| `devices.NAME.{option}" in page, (type_name, option)
    assert "| `scan_period` | duration | `\"10ms\"` |" in page  # a duration as TOML writes it


def test_every_keyword_of_the_grammar_is_listed(generated):
    page = generated["reference/instructions.md"]
    for word in ("`LDF`", "`XORN`", "`AND(N`", "`MRD`", "`JMPCN`", "`ENDC`", "`OUT_BLK`",
                 "`PID`", "`EXCHn`", "`SRn:`", "`=*=`", "`#D`", "`CONCATW`", "`INTO_TO_REAL`"):
        assert word in page, word
    assert "| `LD`, `LDN`, `LDR`, `LDF` |" in page  # one terminal's spellings, in order


def test_every_function_code_is_listed(generated):
    from softplc.modbus import regmap

    page = generated["reference/modbus-map.md"]
    for f in regmap.FUNCTIONS.values():
        assert f"| {f.code} | {f.name} |" in page
    for c in regmap.ExceptionCode:
        assert f"`{c.name}`" in page


def test_a_keyword_regex_the_expander_cannot_list_is_refused():
    with pytest.raises(ValueError, match="unbounded"):
        gen_docs.spellings("/(AB)+/i", [])
