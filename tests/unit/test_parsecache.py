"""A program text parsed again is a copy of the first parse (softplc/il/parsecache.py)."""

from __future__ import annotations

import pytest

from softplc.errors import ParseError
from softplc.il import parsecache
from softplc.il.parser import parse
from softplc.twido.profile import DEFAULT_PROFILE
from softplc.twido.symbols import Symbol, SymbolTable

TEXT = "LD START\nANDN STOP\nST MOTOR\n"


def table(motor: str) -> SymbolTable:
    return SymbolTable([Symbol("START", "%I0.0"), Symbol("STOP", "%I0.1"),
                        Symbol("MOTOR", motor)], DEFAULT_PROFILE)


def test_a_second_parse_is_an_equal_copy_that_owns_its_tree():
    first = parse(TEXT, "m.il", table("%Q0.0"))
    second = parse(TEXT, "m.il", table("%Q0.0"))  # an equal table: the same key
    assert second == first and second is not first
    second.rungs[0].instructions.clear()  # a caller may change its tree...
    assert parse(TEXT, "m.il", table("%Q0.0")) == first  # ...the next one is whole


def test_what_decides_the_result_is_in_the_key():
    q0, q1 = parse(TEXT, "m.il", table("%Q0.0")), parse(TEXT, "m.il", table("%Q0.1"))
    assert str(q0.rungs[0].instructions[-1].target) == "%Q0.0"
    assert str(q1.rungs[0].instructions[-1].target) == "%Q0.1"
    assert parse(TEXT, "other.il", table("%Q0.0")).file == "other.il"
    with pytest.raises(ParseError, match="MOTOR"):  # no symbols: the names are unknown
        parse(TEXT, "m.il")


def test_a_refused_text_is_refused_every_time():
    for _ in range(2):
        with pytest.raises(ParseError) as e:
            parse("LD %I0.0\nST %Q0.0\nBOGUS 3\n", "bad.il")
        assert e.value.program is not None  # what parsed, for the later checks


def test_a_long_text_is_not_kept(monkeypatch):
    monkeypatch.setattr(parsecache, "CACHE_MAX_CHARS", len(TEXT) - 1)
    before = dict(parsecache._kept)
    parse(TEXT, "long.il", table("%Q0.2"))
    assert parsecache._kept == before


def test_the_cache_is_bounded(monkeypatch):
    monkeypatch.setattr(parsecache, "CACHE_ENTRIES", 3)
    for k in range(6):
        parse(f"LD %I0.{k}\nST %Q0.0\n", f"p{k}.il")
    assert len(parsecache._kept) == 3
    assert ("LD %I0.5\nST %Q0.0\n", "p5.il", None) in parsecache._kept
