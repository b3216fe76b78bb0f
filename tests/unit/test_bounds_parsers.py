"""Every parser bounds its input (issue 31 items 3 and 6): numbers past Python's 4,300-digit
`int()` limit, REAL constants beyond single precision, deep TOML, binary symbol files and
over-long addresses are coded errors at line:col, never a traceback."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.config import parse_toml, read_toml
from softplc.errors import AddressError, Code, ConfigCode, ConfigError, ParseError
from softplc.il.parser import parse, parse_file
from softplc.limits import MAX_NUMBER_DIGITS, MAX_TOML_DEPTH, BoundsError, check_toml
from softplc.twido.address import parse_address
from softplc.twido.symbols import read_csv, read_csv_file

BIG = "9" * 5000


@pytest.mark.parametrize("source, line, col", [
    (f"LD 1\n[ %MW0 := {BIG} ]\n", 2, 11),          # the fast path's constant
    (f"LD [ %MW0 > {BIG} ]\nST %M0\n", 1, 13),
    (f"LD 1\n[ %MW0 := SHL( %MW1, {BIG} ) ]\n", 2, 22),  # through Lark
    (f"LD 1\n[ %MW0 := #{'F' * 5000} ]\n", 2, 12),
    (f"LD 1\n[ %MF0 := 1.0E{BIG} ]\n", 2, 13),  # the run "0E99..." (hex digits)
    (f"LD 1\nJMP %L{BIG}\n", 2, 7),
    (f"=*= {BIG}\n", 1, 5),
    (f"LD %MW{BIG}:X1\nST %M1\n", 1, 7),
])
def test_numbers_past_the_digit_limit_are_constant_errors(source, line, col):
    with pytest.raises(ParseError) as e:
        parse(source, "p.il")
    d = e.value.diagnostics[0]
    assert (d.line, d.column, d.code) == (line, col, Code.CONSTANT)
    assert f"at most {MAX_NUMBER_DIGITS} digits" in str(d) and len(str(d)) < 300


def test_a_long_number_in_a_comment_is_a_comment():
    assert parse(f"(* {BIG} *)\nLD 1\nST %M0\n").rungs


@pytest.mark.parametrize("constant", ["1.0E39", "-3.5E38", "1.0E309"])
def test_real_constants_beyond_single_precision_are_refused(constant):
    with pytest.raises(ParseError) as e:
        parse(f"LD 1\n[ %MF0 := {constant} ]\n")
    assert e.value.diagnostics[0].code == Code.CONSTANT
    assert "single-precision" in str(e.value)
    assert parse("LD 1\n[ %MF0 := 3.4E38 ]\n").rungs  # the largest REAL is fine


def test_the_program_file_is_size_capped(tmp_path, monkeypatch):
    import softplc.il.parser as parser
    monkeypatch.setattr(parser, "MAX_PROGRAM_BYTES", 100)
    p = tmp_path / "p.il"
    p.write_text("LD 1\nST %M0\n" * 20)
    with pytest.raises(ParseError, match="larger than") as e:
        parse_file(p)
    assert e.value.diagnostics[0].code == Code.CANNOT_READ


def test_addresses_are_bounded_before_their_numbers_are_converted():
    with pytest.raises(AddressError, match="characters, at most"):
        parse_address(f"%MW{BIG}")


@pytest.mark.parametrize("text, line, col, words", [
    (f"scan_period = {BIG}\n", 1, 15, "a number of 5000"),
    (f"a = 1\nb = 1.{BIG}\n", 2, 7, "a number of 5000"),
    ("x = " + "[" * 3000 + "]" * 3000 + "\n", 1, 5 + MAX_TOML_DEPTH, "nested more than"),
    ("x = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n", 1, None, "nested more than"),
])
def test_configuration_toml_is_bounded(text, line, col, words):
    with pytest.raises(BoundsError) as b:
        check_toml(text)
    assert b.value.line == line and (col is None or b.value.col == col)
    with pytest.raises(ConfigError, match=words) as e:
        parse_toml(text, "c.toml")
    assert e.value.issues[0].code == ConfigCode.FILE and len(str(e.value)) < 300


def test_toml_strings_and_comments_are_not_counted():
    text = f'name = "{BIG}"\n# {"[" * 100}\nnote = """\n{"{" * 100}\n"""\n'
    assert parse_toml(text)["name"] == BIG


def test_a_binary_configuration_file_is_a_file_error(tmp_path):
    p = tmp_path / "c.toml"
    p.write_bytes(b"scan_period = 1\n\x00\x01\x02")
    with pytest.raises(ConfigError, match=r"2:1: the file is not a text file") as e:
        read_toml(p)
    assert e.value.issues[0].code == ConfigCode.FILE


@pytest.mark.parametrize("data, where", [
    (bytes(range(256)) * 8, ":1:1: the symbol file is not a text file"),
    # no NUL, but bytes neither UTF-8 nor cp1252 has (0x81 0x8d 0x8f 0x90 0x9d)
    (b"%M0,START\r\n%M1,ST\x81OP\r\n", ":2:7: the symbol file is not a text file: byte 0x81"),
])
def test_a_binary_symbol_file_is_a_coded_error(tmp_path, data, where):
    p = tmp_path / "s.csv"
    p.write_bytes(data)
    with pytest.raises(ConfigError) as e:
        read_csv_file(p)
    assert where in str(e.value) and e.value.issues[0].code == ConfigCode.FILE
    cfg = tmp_path / "c.toml"  # wherever a configuration names the file
    cfg.write_text('symbols_file = "s.csv"\n')
    with pytest.raises(ConfigError, match=where.split(": ")[0]):
        PLC.from_source("LD %I0.0\nST %Q0.0\n", cfg)


def test_symbol_csv_rows_are_bounded():
    with pytest.raises(ConfigError, match=r"s.csv:1: not a symbol line: field larger"):
        read_csv('%M0,"' + "A" * 200_000 + "\n", "s.csv")
    assert read_csv("%M0,START,\xe9t\xe9\n")[0].comment == "\xe9t\xe9"
