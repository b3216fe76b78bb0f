"""Symbols (softplc.twido.symbols): declared in the configuration or a CSV file, used wherever an
address is (IL, plc[...], the REPL, the ladder views, the formatter), imported and exported
by `softplc symbols`."""

from __future__ import annotations

import pytest

from softplc import PLC, ladder
from softplc.cli import main as softplc
from softplc.debug.session import Session
from softplc.errors import AddressError, Code, ConfigError, ParseError
from softplc.twido.symbols import SymbolTable, read_csv

pytest_plugins = ["pytester"]

MOTOR = """\
(* start / stop with self-hold, written with symbols *)
LD    START_PB
OR    MOTOR_K1
ANDN  stop_pb
ST    MOTOR_K1
LD    MOTOR_K1
IN    RUN_TIME
LD    RUN_TIME.Q
ST    RUN_LAMP
"""
SYMBOLS = {"START_PB": "%I0.0", "STOP_PB": {"address": "%I0.1", "comment": "NO"},
           "MOTOR_K1": {"address": "%Q0.0", "comment": "main contactor"},
           "RUN_LAMP": "%Q0.1", "RUN_TIME": "%TM0"}
CONFIG = {"timers": {"%TM0": {"type": "TON", "base": "100ms", "preset": 5}},
          "symbols": SYMBOLS}


def test_a_program_written_with_symbols_runs():
    plc = PLC.from_source(MOTOR, CONFIG)
    plc["START_PB"] = 1
    plc.scan()
    plc["start_pb"] = 0  # names are matched whatever their case
    plc.scan()
    assert plc["MOTOR_K1"] and plc["%Q0.0"] and not plc["RUN_LAMP"]
    plc.run(1.0)
    assert plc["RUN_TIME.Q"] and plc["RUN_LAMP"]
    plc["STOP_PB"] = 1
    plc.scan()
    assert not plc["MOTOR_K1"]
    with pytest.raises(AddressError, match=r"unknown symbol 'MOTOR_K2' \(did you mean "
                                           r"MOTOR_K1\?\)"):
        plc["MOTOR_K2"]


def test_unknown_symbols_are_listed_with_line_column_and_a_guess():
    src = "LD    START_PB\nANDN  STOPP_PB\nST    MOTOR_K1\nLD    RUN_TIME.Q\nST    LAMP\n"
    with pytest.raises(ParseError) as e:
        PLC.from_source(src, CONFIG, file="m.il")
    d1, d2 = e.value.diagnostics
    assert (d1.line, d1.column, d1.text, d1.code) == (2, 7, "STOPP_PB", Code.SYMBOL)
    assert str(d1).startswith("m.il:2:7: unknown symbol 'STOPP_PB' (did you mean STOP_PB?)")
    assert (d2.line, d2.column) == (5, 7) and "LAMP" in d2.message
    with pytest.raises(ParseError, match=r"nor a symbol \(none is declared"):
        PLC.from_source("LD START_PB\nST %Q0.0\n")


@pytest.mark.parametrize("symbols, message", [
    ({"1START": "%I0.0"}, "a letter or _"),
    ({"LD": "%I0.0"}, "is an Instruction List keyword"),
    ({"SR3": "%I0.0"}, "is an Instruction List keyword"),
    ({"A": "%I0.0", "a": "%I0.1"}, "declared twice"),
    ({"A": "%I0.0", "B": "%I0.0"}, "%I0.0 has two symbols: A and B"),
    ({"A": "%MW0:4"}, "a range"),
    ({"A": "%Q0.99"}, "has 16 outputs"),
    ({"A": 5}, 'symbols.A: "ADDRESS"'),
    ({"A": {"address": "%I0.0", "colour": "red"}}, "symbols.A.colour: unknown key"),
])
def test_bad_declarations_are_clear_errors(symbols, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(".", r"\.")):
        PLC.from_source("LD %I0.0\nST %Q0.0\n", {"symbols": symbols})


def test_csv_file_beside_the_configuration(tmp_path):
    (tmp_path / "io.csv").write_bytes(
        "Adresse;Symbole;Commentaire\r\n%I0.0;START_PB;démarrage\r\n"
        "%Q0.0;MOTOR_K1;\r\n".encode("cp1252"))  # TwidoSuite on Windows: ANSI, CRLF
    (tmp_path / "m.toml").write_text('symbols_file = "io.csv"\n[symbols]\nSTOP_PB = "%I0.1"\n')
    (tmp_path / "m.il").write_text("LD START_PB\nANDN STOP_PB\nST MOTOR_K1\n")
    plc = PLC.from_file(tmp_path / "m.il", tmp_path / "m.toml")
    assert plc.symbols.comment_of(plc.symbols.ref("START_PB")) == "démarrage"
    plc["%I0.0"] = 1
    plc.scan()
    assert plc["MOTOR_K1"]
    (tmp_path / "m.toml").write_text('symbols_file = "nope.csv"\n')
    with pytest.raises(ConfigError, match="nope.csv: no such symbol file"):
        PLC.from_file(tmp_path / "m.il", tmp_path / "m.toml")


def test_csv_layouts_and_errors():
    rows = read_csv("%I0.0,START_PB,start\n%Q0.0\tX\n".replace("\t", ","))
    assert [(s.address, s.name, s.comment) for s in rows] == \
        [("%I0.0", "START_PB", "start"), ("%Q0.0", "X", "")]
    assert [s.name for s in read_csv("Address\tSymbol\n%M0\tBUSY\n")] == ["BUSY"]
    assert [(s.address, s.name) for s in read_csv("Symbol;Address\nBUSY;%M0\n")] == \
        [("%M0", "BUSY")]  # symbol first: read as well
    with pytest.raises(ConfigError, match=r"x.csv:2: expected ADDRESS,SYMBOL"):
        read_csv("%I0.0,A\n%I0.1\n", "x.csv")
    table = SymbolTable(read_csv('%Q0.0,K1,"main, 400 V"\n%I0.0,S1,\n'))
    assert read_csv(table.to_csv()) == list(table)  # %I before %Q, comma kept by quoting


def test_repl_watch_and_print_by_name():
    s = Session(PLC.from_source(MOTOR, CONFIG))
    assert s.execute("watch MOTOR_K1") == "watch #1 %Q0.0 MOTOR_K1 (now 0)"
    s.execute("set START_PB 1")
    assert "watch #1 %Q0.0 MOTOR_K1: 0 -> 1" in s.execute("continue")
    assert s.execute("print RUN_TIME.Q").startswith("%TM0.Q RUN_TIME.Q = 0")
    assert "did you mean START_PB" in s.execute("force STRAT_PB 1")
    assert "START_PB" in s.addresses()  # tab completion


def test_ladder_shows_the_symbol_above_the_address():
    plc = PLC.from_source(MOTOR, CONFIG)
    text = ladder.render_text(plc.ast.rungs[0])
    names, addresses = text.splitlines()[1:3]
    for name, address in (("START_PB", "%I0.0"), ("STOP_PB", "%I0.1"),
                          ("MOTOR_K1", "%Q0.0")):
        # each name above its address, centred on the same column
        col = addresses.index(address) + len(address) / 2
        assert abs(names.index(name) + len(name) / 2 - col) <= 1, (name, text)
    assert "RUN_TIME.Q" in ladder.render_text(plc.ast.rungs[2])
    svg = ladder.render_program_svg(plc.ast)
    assert ">START_PB</text>" in svg and ">%I0.0</text>" in svg
    # a program without symbols draws as before: no line added
    plain = PLC.from_source("LD %I0.0\nST %Q0.0\n")
    assert len(ladder.render_text(plain.ast.rungs[0]).splitlines()) == 3


def test_formatter_keeps_the_names_as_written(tmp_path, capsys):
    prog = tmp_path / "m.il"
    prog.write_text("ld start_pb\nANDN %I0.1\nst MOTOR_K1   (* K1 *)\n")
    assert softplc(["check", "--format", str(prog)]) == 0  # no configuration needed
    assert capsys.readouterr().out == \
        "LD    start_pb\nANDN  %I0.1\nST    MOTOR_K1  (* K1 *)\n"
    cfg = tmp_path / "m.toml"
    cfg.write_text('[symbols]\nSTART_PB = "%I0.0"\nSTOP_PB = "%I0.1"\nMOTOR_K1 = "%Q0.0"\n')
    assert softplc(["check", "--format", str(prog), "--config", str(cfg)]) == 0
    # the declared spelling; an address written as such stays an address
    assert capsys.readouterr().out == \
        "LD    START_PB\nANDN  %I0.1\nST    MOTOR_K1  (* K1 *)\n"


def test_symbols_export_and_import(tmp_path, capsys):
    cfg = tmp_path / "m.toml"
    cfg.write_text('scan_period = "10ms"\n[symbols]\nMOTOR_K1 = { address = "%Q0.0", '
                   'comment = "main; 400 V" }\nSTART_PB = "%I0.0"\n')
    out = tmp_path / "m.csv"
    assert softplc(["symbols", "export", "--config", str(cfg), "-o", str(out),
                    "--delimiter", ";"]) == 0
    assert out.read_text() == \
        'Address;Symbol;Comment\n%I0.0;START_PB;\n%Q0.0;MOTOR_K1;"main; 400 V"\n'
    assert softplc(["symbols", "import", str(out)]) == 0
    assert capsys.readouterr().out == ('[symbols]\nSTART_PB = "%I0.0"\nMOTOR_K1 = { address '
                                       '= "%Q0.0", comment = "main; 400 V" }\n')
    assert softplc(["symbols", "import", str(out), "--config", str(cfg)]) == 1
    assert "already declares symbols" in capsys.readouterr().err
    fresh = tmp_path / "fresh.toml"
    fresh.write_text('scan_period = "10ms"\n')
    assert softplc(["symbols", "import", str(out), "--config", str(fresh)]) == 0
    plc = PLC.from_source("LD START_PB\nST MOTOR_K1\n", fresh)
    assert plc.symbols.get("motor_k1").comment == "main; 400 V"
    bad = tmp_path / "bad.csv"
    bad.write_text("%I0.0,LD\n")
    assert softplc(["symbols", "import", str(bad)]) == 1
    assert "keyword" in capsys.readouterr().err


def test_plugin_reads_symbols(pytester):
    pytester.makefile(".il", motor=MOTOR)
    pytester.makefile(".toml", motor='[timers."%TM0"]\npreset = 5\n[symbols]\n'
                      'START_PB = "%I0.0"\nSTOP_PB = "%I0.1"\nMOTOR_K1 = "%Q0.0"\n'
                      'RUN_LAMP = "%Q0.1"\nRUN_TIME = "%TM0"\n')
    pytester.makepyfile(test_motor="""
import pytest
from softplc.testing import pulse

@pytest.mark.plc_program("motor.il", config="motor.toml")
def test_start(plc):
    pulse(plc, "START_PB")
    assert plc["MOTOR_K1"]
""")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)


def test_an_address_without_its_percent_sign_gets_the_address_as_a_guess():
    with pytest.raises(ParseError) as e:
        PLC.from_source("LD I0.0\nST Q0.1\n", CONFIG)
    d1, d2 = e.value.diagnostics
    assert (d1.line, d1.column, d1.text) == (1, 4, "I0.0")
    assert d1.message.endswith("did you mean %I0.0?") and "%Q0.1?" in d2.message
