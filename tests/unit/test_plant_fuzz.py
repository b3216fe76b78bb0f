"""Mutated plant files: a plant file either loads (and the plant then runs) or is refused
with a PlantError (each problem with its line) or its controllers' own ConfigError /
ProgramError. Never another exception. The seed is the example plant
(ladder_programs/plant); hypothesis swaps values for other types or out-of-range ones,
deletes keys or adds unknown ones."""

from __future__ import annotations

import copy
import json
import math
import shutil
import tomllib
from pathlib import Path
from typing import Any

import pytest
from doc_paths import at, key_paths
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softplc.errors import ConfigError, ProgramError
from softplc.plant import Plant, PlantError
from softplc.plant.model import MAX_PLANT_BYTES

SEED = Path(__file__).resolve().parents[2] / "ladder_programs" / "plant"
PLANT = tomllib.loads((SEED / "plant.toml").read_text(encoding="utf-8"))

scalars = st.one_of(
    st.integers(-2**40, 2**40), st.sampled_from([0, -1, 1, 7, 8, 255, 256, 2**63 - 1]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.inf, -math.inf, math.nan, 1e308, 0.5]),
    st.booleans(),
    st.sampled_from(["", "master", "filler", "belt", "belt:run", "master:%Q0.0",
                     "filler:%I0.0", "master:%I0.0", "x:%Q0.0", "10ms", "0ms", "inf",
                     "conveyor", "exch", "remote_link", "station.il", "nope.il", "10.0.0.1",
                     "%MW0", "a" * 40]),
    st.text(st.characters(blacklist_categories=("Cs",)), max_size=8),
)
values = st.one_of(scalars, st.lists(scalars, max_size=4),
                   st.dictionaries(st.sampled_from(["1", "2", "x", "fill", "type"]), scalars,
                                   max_size=3))


def toml_value(x: Any) -> str:
    """`x` as a TOML value (inline tables and arrays; strings as JSON escapes them, which
    TOML's basic strings read alike)."""
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf") if math.isinf(x) \
            else repr(x)
    if isinstance(x, (int, str)):
        return json.dumps(x, ensure_ascii=False)
    if isinstance(x, list):
        return "[" + ", ".join(toml_value(v) for v in x) + "]"
    return "{ " + ", ".join(f"{toml_value(str(k))} = {toml_value(v)}"
                            for k, v in x.items()) + " }"


PATHS = key_paths(PLANT)


@st.composite
def mutated(draw: st.DrawFn) -> dict[str, Any]:
    doc = copy.deepcopy(PLANT)
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(PATHS))
        try:
            parent = at(doc, where[:-1])
            kind = draw(st.integers(0, 5))
            if kind == 0 and isinstance(parent, dict):
                del parent[where[-1]]
            elif kind == 1 and isinstance(parent, dict):
                parent[draw(st.sampled_from(["bogus", "Type", "peer"]))] = draw(values)
            else:
                parent[where[-1]] = draw(values)
        except (KeyError, IndexError, TypeError):
            pass  # an earlier mutation replaced or removed this path
    return doc


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("plant")
    for f in SEED.iterdir():
        shutil.copy(f, d / f.name)
    return d


@settings(max_examples=examples(120), deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(doc=mutated())
def test_mutated_plant_file_loads_or_is_refused_with_its_line(folder: Path, doc) -> None:
    f = folder / "fuzz.toml"
    f.write_text("".join(f"{toml_value(k)} = {toml_value(v)}\n" for k, v in doc.items()))
    assert tomllib.loads(f.read_text()) is not None
    try:
        plant = Plant.from_file(f)
    except PlantError as e:
        assert e.plant_issues and all(str(i).startswith(f"{f}:") for i in e.plant_issues)
        return
    except (ConfigError, ProgramError) as e:
        assert str(e)
        return
    try:
        plant.run(0.2)
    finally:
        plant.close()


def test_an_oversized_plant_file_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "big.toml"
    f.write_text("# " + "x" * MAX_PLANT_BYTES + "\n")
    with pytest.raises(PlantError, match="a plant file has at most"):
        Plant.from_file(f)
