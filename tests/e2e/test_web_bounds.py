"""POST /api/program and the JSON API bound their input (issue 31 item 3): a 5,000-digit
number in the program, the configuration or the JSON body is a 400 with a coded error (the
program's line:col), never a 500 with a traceback; NaN and Infinity are no JSON numbers."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import pytest
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from input_fuzz import online_change
from test_web_api import STAR

from softplc.commands.io import IoError

SOURCE = STAR.read_text()
BIG = "9" * 5000


def test_a_huge_number_in_the_program_is_a_400_with_its_line_and_column(star):
    bad = SOURCE + f"\nLD 1\n[ %MW90 := {BIG} ]\n"
    line = bad.count("\n", 0, bad.index(BIG)) + 1
    with pytest.raises(IoError, match=r"\(HTTP 400\)") as e:
        star.client().request("program", {"program": bad})
    assert f":{line}:12: a number of 5000 digits" in str(e.value)
    assert star.plc.program_version == 0


@pytest.mark.parametrize("config, words", [
    (f"scan_period = {BIG}\n", "1:15: a number of 5000"),
    ("x = " + "[" * 3000 + "]" * 3000, "nested more than"),
])
def test_a_bad_configuration_text_is_a_400(star, config, words):
    with pytest.raises(IoError, match=r"\(HTTP 400\)") as e:
        star.client().request("program", {"program": SOURCE, "config": config})
    assert words in str(e.value) and "Traceback" not in str(e.value)


@pytest.mark.parametrize("body, words", [
    (b'{"object": "%MW0", "value": ' + BIG.encode() + b"}", "a number of 5000 characters"),
    (b'{"object": "%MF0", "value": NaN}', "NaN is no JSON number"),
    (b'{"object": "%MF0", "value": -Infinity}', "-Infinity is no JSON number"),
])
def test_json_bodies_refuse_huge_and_non_finite_numbers(star, body, words):
    req = urllib.request.Request(star.client().base + "write", data=body, method="POST",
                                 headers={"Content-Type": "application/json"})
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req, timeout=5)
    assert e.value.code == 400 and words in json.loads(e.value.read())["error"]


def test_mutated_online_changes_are_answered_never_with_a_500(star):
    base = star.client().base

    @settings(max_examples=examples(160), deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        assert online_change(base, data) in ("read", "refused")

    run()
