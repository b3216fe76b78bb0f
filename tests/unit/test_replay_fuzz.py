"""Mutated counterexample files (`softplc verify --cex`): `softplc replay` either plays one
(every scan, the table, the rungs) or refuses it with a SoftPLCError, never another
exception. The seed has the shape verify writes for star_delta_defect.il; hypothesis swaps
values for other types or out-of-range ones, deletes keys or adds unknown ones."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softplc.errors import SoftPLCError
from softplc.plc import PLC
from softplc.verify.player import TracePlayer
from softplc.verify.replay import CEX_FORMAT, read_cex

LP = Path(__file__).resolve().parents[2] / "ladder_programs"
ROW = {"inputs": {"%I0.0": 1, "%I0.1": 1, "%I0.2": 0, "%I0.3": 1, "period_ms": 1000},
       "values": {"%I0.2": 0, "%Q0.0": 1}, "objects": {"%Q0.0": 1, "%TM0.V": 0}}
SEED = {"format": CEX_FORMAT, "program": "star_delta_defect.il", "config": None,
        "counterexamples": [{"requirement": "overload", "scans": [ROW, copy.deepcopy(ROW)],
                             "check": "%I0.2 = 0 -> NOT (%Q0.0 OR %Q0.1 OR %Q0.2)"}]}

scalars = st.one_of(
    st.integers(-2**70, 2**70), st.sampled_from([0, -1, 1, 65535, 65536, 2**31, 2**63]),
    st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([1e308, -0.0, 0.5]),
    st.booleans(), st.none(),
    st.sampled_from(["", "%I0.0", "%Q0.2", "%MW0", "%TM0.V", "%ZZ1", "period_ms",
                     "never %Q0.2", "NOT (", "%I0.0 = 0 -> %Q0.0 within 50ms", "a" * 60]),
    st.text(max_size=8),
)
values = st.one_of(scalars, st.lists(scalars, max_size=3),
                   st.dictionaries(st.sampled_from(["%I0.0", "%IW0.0", "%MW5", "%Q0.1",
                                                    "period_ms", "%S0", "%KW0", "%ZZ1",
                                                    "%TM0.V", "x"]),
                                   scalars, max_size=3))


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    items = node.items() if isinstance(node, dict) else (
        enumerate(node) if isinstance(node, list) else ())
    out = []
    for k, v in items:
        out.append(prefix + (k,))
        out += _paths(v, prefix + (k,))
    return out


@st.composite
def mutated(draw: st.DrawFn) -> dict[str, Any]:
    doc = copy.deepcopy(SEED)
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(_paths(doc) or [("format",)]))
        parent: Any = doc
        try:
            for k in where[:-1]:
                parent = parent[k]
            action = draw(st.sampled_from(["set", "delete", "add"]))
            if action == "set":
                parent[where[-1]] = draw(values)
            elif action == "delete":
                del parent[where[-1]]
            elif isinstance(parent, dict):
                parent[draw(st.sampled_from(["%I0.0", "%MW3", "extra", "values"]))] = \
                    draw(values)
        except (KeyError, IndexError, TypeError):
            pass  # an earlier mutation removed the path
    return doc


def make() -> Any:
    return PLC.from_file(LP / "star_delta_defect.il", config=LP / "star_delta.toml",
                         devices=False)


@settings(max_examples=examples(200), deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(doc=mutated())
def test_a_mutated_counterexample_plays_or_is_refused(tmp_path, doc):
    path = tmp_path / "cex.json"
    path.write_text(json.dumps(doc, allow_nan=True))
    try:
        item = read_cex(path)["counterexamples"][0]
        player = TracePlayer(make, item)
    except SoftPLCError as e:
        assert str(e)
        return
    try:
        for n in (player.total, 0, player.total):
            player.goto(n)
            frame = player.frame()
            assert frame["scan"] == n and frame["status"]
        assert len(player.rung_svgs()) == len(player.plc.ast.rungs)
        assert len(player.history()) == player.total
    except SoftPLCError as e:
        assert str(e)
    finally:
        player.close()


def test_the_seed_plays():
    path_item = copy.deepcopy(SEED["counterexamples"][0])
    player = TracePlayer(make, path_item)
    try:
        assert player.violated_at == 1 and player.total == 2
        assert not math.isnan(player.goto(2))
    finally:
        player.close()
