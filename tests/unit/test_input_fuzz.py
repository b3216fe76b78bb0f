"""The file readers' mutation fuzzers (tests/input_fuzz.py) at the suite's budget: a
mutated requirement file, symbol CSV, DXF drawing or G-code program is read or refused
with the reader's coded error, never a traceback (issue 31, issue 34 item 6)."""

from __future__ import annotations

import pytest
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from input_fuzz import TARGETS


@pytest.mark.parametrize("name", list(TARGETS))
def test_mutated_inputs_are_read_or_refused_with_a_coded_error(name):
    target, full = TARGETS[name]

    @settings(max_examples=examples(full // 10), deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        assert target(data) in ("read", "refused")

    run()
