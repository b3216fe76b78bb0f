"""One text per kind of value (softplc.twido.display): `softplc io`, the debugger's print, watch
and history, and the live ladder show a bit, a word, a float and a block the same way."""

from __future__ import annotations

import numpy as np

from softplc import PLC
from softplc.debug.session import Session
from softplc.twido.address import parse_address
from softplc.twido.display import format_value

TIMER = {"timers": {"%TM0": {"type": "TON", "base": "100ms", "preset": 5}}}


def test_a_bit_reads_1_or_0_whatever_its_python_type():
    q = parse_address("%Q0.0")
    # the memory image (numpy.bool_), PLC[...] (bool), the web API's JSON (true or 1)
    assert [format_value(v, q) for v in (np.bool_(True), True, 1, np.bool_(False), 0)] == \
        ["1", "1", "1", "0", "0"]
    assert format_value(True) == "1" and format_value(False) == "0"  # no ref: still a bit


def test_words_floats_and_unreadable():
    assert format_value(np.int16(-3), parse_address("%MW0")) == "-3"
    assert format_value(np.float32(0.1), parse_address("%MF0")) == "0.1"
    assert format_value(1 / 3, parse_address("%MF0")) == "0.3333333"
    assert format_value(None, parse_address("%MW0")) == "?"


def test_a_block_is_the_same_text_from_memory_and_from_the_api():
    plc = PLC.from_source("LD %I0.0\nIN %TM0\n", TIMER)
    tm0 = parse_address("%TM0")
    from_memory = format_value(plc["%TM0"], tm0)
    api_json = {"Q": 0, "V": 0, "P": 5, "type": "TON", "base": "100ms"}  # /api/read
    assert from_memory == format_value(api_json, tm0) == "TON base 100ms Q=0 V=0 P=5"


def test_repl_print_watch_and_history_agree():
    plc = PLC.from_source("LD %I0.0\nST %Q0.0\nLD %I0.0\nIN %TM0\n", TIMER)
    s = Session(plc)
    assert s.execute("watch %Q0.0") == "watch #1 %Q0.0 (now 0)"
    s.execute("set %I0.0 1")
    stop = s.execute("scan")
    assert "watch #1 %Q0.0: 0 -> 1" in stop and "True" not in stop
    assert s.execute("print %Q0.0").startswith("%Q0.0 = 1")  # (field 0): stopped mid-scan
    assert s.execute("print %TM0") == "%TM0 = TON base 100ms Q=0 V=0 P=5"
    hist = s.execute("history")
    assert "0 -> 1" in hist and "False" not in hist and "True" not in hist
