"""`softplc map` and softplc.modbus.tags: the Modbus map of a program (issue 24)."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from softplc import PLC
from softplc.cli import main
from softplc.compiler.resolve import object_uses
from softplc.il.parser import parse
from softplc.modbus import tags
from softplc.modbus.regmap import COILS, REGISTERS, ReadOnly

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "ladder_programs"

SOURCE = """\
LD %I0.0
ST %Q0.0
ST %M3
[ %MW10 := %MW11 + 1 ]
[ %MD20 := %MD22 ]
[ %MF30 := %MF32 ]
[ %MW40:4 := %MW50:4 ]
LD %MW60:X2
ST %M4
[ %MW70 := %MW71[%MW72] ]
[ %MW80 := %SW0 ]
LD 1
IN %TM0
LD %TM0.Q
ST %M5
[ INC %MW90 ]
"""
CONFIG = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 5}}}


def program_map(read_only: ReadOnly | None = None, **kw) -> tags.ProgramMap:
    return tags.build(parse(SOURCE), read_only or ReadOnly(), **kw)


def by_address(pmap: tags.ProgramMap) -> dict[str, tags.Tag]:
    return {t.address: t for t in pmap.tags}


def test_words_and_bits_get_their_table_address_and_width():
    t = by_address(program_map())
    assert (t["%M3"].space, t["%M3"].start, t["%M3"].count) == (COILS, 3, 1)
    assert (t["%MW10"].space, t["%MW10"].start, t["%MW10"].count) == (REGISTERS, 10, 1)
    assert (t["%MD20"].start, t["%MD20"].count, t["%MD20"].type) == (20, 2, "INT32")
    assert (t["%MF32"].start, t["%MF32"].count, t["%MF32"].type) == (32, 2, "REAL")
    assert (t["%MW40:4"].start, t["%MW40:4"].count) == (40, 4)
    assert t["%MW60:X2"].type == "BOOL" and t["%MW60:X2"].start == 60
    assert t["%MW10"].reference == 40011 and t["%M3"].reference == 4


def test_how_the_program_uses_each_object():
    t = by_address(program_map())
    assert t["%MW10"].program == "write" and t["%MW11"].program == "read"
    assert t["%M3"].program == "write"
    assert t["%MW90"].program == "read/write"  # INC reads and writes
    assert t["%MW72"].program == "read"  # the index word of %MW71[%MW72]
    assert "indexed" in t["%MW71[%MW72]"].note


def test_function_codes_follow_the_register_map():
    t = by_address(program_map())
    assert t["%M3"].read_fcs == (1, 2) and t["%M3"].write_fcs == (5, 15)
    assert t["%MW10"].read_fcs == (3, 4, 23) and t["%MW10"].write_fcs == (6, 16, 23)
    # a 32-bit object or a table is written whole by the multi-register writes only
    assert t["%MD20"].write_fcs == (16, 23) and t["%MW40:4"].write_fcs == (16, 23)


def test_read_only_ranges_and_device_status_words_refuse_writes():
    ro = ReadOnly(registers=((10, 12),), coils=((3, 4),))
    t = by_address(program_map(ro, device_words={"X": [(20, 22)]}))
    for name in ("%MW10", "%MW11", "%M3", "%MD20"):
        assert t[name].access == "read" and t[name].write_fcs == (), name
    assert "device X" in t["%MD20"].note
    assert t["%MW70"].access == "read/write"


def test_objects_a_host_cannot_reach_are_listed_with_the_way_to_expose_them():
    hidden = {h.address: h for h in program_map().hidden}
    assert set(hidden) == {"%I0.0", "%Q0.0", "%SW0", "%TM0"}  # %TM0 once, not per field
    assert hidden["%Q0.0"].line == 2 and "ST %M" in hidden["%Q0.0"].why
    assert hidden["%I0.0"].program == "read" and hidden["%Q0.0"].program == "write"


def test_symbols_fill_the_tag_column():
    pmap = program_map(symbols={"%MW10": ("SPEED_SP", "set point, rpm")})
    row = next(csv.DictReader(io.StringIO(tags.to_csv(pmap))))
    assert row["address"] == "%M3"
    rows = {r["address"]: r for r in csv.DictReader(io.StringIO(tags.to_csv(pmap)))}
    assert rows["%MW10"]["tag"] == "SPEED_SP" and rows["%MW10"]["comment"] == "set point, rpm"
    assert rows["%MW11"]["tag"] == "%MW11"


def test_csv_has_one_row_per_tag_with_wire_and_modicon_addresses():
    pmap = program_map()
    rows = list(csv.DictReader(io.StringIO(tags.to_csv(pmap))))
    assert tuple(rows[0]) == tags.CSV_COLUMNS
    assert len(rows) == len(pmap.tags)
    md = next(r for r in rows if r["address"] == "%MD20")
    assert (md["table"], md["modbus_address"], md["reference"], md["count"]) == (
        "holding register", "20", "40021", "2")
    assert md["write_fc"] == "16 23"


def test_text_lists_tags_then_the_unreachable_objects():
    text = tags.to_text(program_map())
    head, _, tail = text.partition("Used by the program but not on the Modbus map:")
    assert "%MD20" in head and "20..21" in head
    listed = [line.split()[0] for line in tail.splitlines() if line.strip()]
    assert listed == ["%I0.0", "%Q0.0", "%SW0", "%TM0"]


def test_the_drawing_table_map_from_the_command_line(capsys, tmp_path):
    out = tmp_path / "tags.csv"
    assert main(["map", str(PROGRAMS / "drawing_table.il"), "--config",
                 str(PROGRAMS / "drawing_table.toml"), "--csv", str(out)]) == 0
    rows = {r["address"]: r for r in csv.DictReader(out.open())}
    plc = PLC.from_file(PROGRAMS / "drawing_table.il", PROGRAMS / "drawing_table.toml")
    used = {str(r) for r in object_uses(plc.ast)
            if r.kind in ("M", "MW", "MD", "MF")}
    assert set(rows) == used and "%MW3" in rows
    assert "wrote" in capsys.readouterr().err
    assert main(["map", str(PROGRAMS / "drawing_table.il")]) == 0
    text = capsys.readouterr().out
    assert "%Q1.0" in text.split("not on the Modbus map")[1]


def test_servo_status_words_are_read_only_on_the_servo_table_map(capsys):
    assert main(["map", str(PROGRAMS / "servo_table.il"), "--config",
                 str(PROGRAMS / "servo_table.toml"), "--csv", "-"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    device_rows = [r for r in rows if "status word of device" in r["note"]]
    assert device_rows and all(r["write_fc"] == "" for r in device_rows)


@pytest.mark.parametrize("args", [["map", "nope.il"], ["map", str(PROGRAMS / "drawing_table.il"),
                                                        "--config", "nope.toml"]])
def test_missing_files_are_clear_errors(args, capsys):
    assert main(args) != 0
    assert "no such file" in capsys.readouterr().err


def test_the_configuration_s_symbols_name_the_tags(capsys):
    assert main(["map", str(PROGRAMS / "star_delta.il"), "--config",
                 str(PROGRAMS / "star_delta.toml"), "--csv", "-"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    plc = PLC.from_file(PROGRAMS / "star_delta.il", PROGRAMS / "star_delta.toml")
    named = {s.address: s.name for s in plc.symbols}
    tagged = [r for r in rows if r["address"] in named]
    assert tagged and all(r["tag"] == named[r["address"]] for r in tagged)


def test_a_hidden_block_is_shown_with_its_own_word_field():
    assert "%C0.V ]" in tags.block_why("%C0", "C")
    assert "%DR1.S ]" in tags.block_why("%DR1", "DR")
    assert "%TM0.V ]" in {h.address: h for h in program_map().hidden}["%TM0"].why


def test_each_hidden_row_hints_its_own_address_and_a_free_target():
    """The hint names the row's own object and a %M/%MW the program does not use, a
    different one on each row (issue 33: it was `LD %I0.0 / ST %M100` on every row)."""
    prog = parse("LD %I0.3\nST %M0\nLD %I0.5\nST %Q0.2\n"
                         "[ %MW0 := %IW1.0 ]\n[ %MW1 := %KW4 ]\n")
    why = {h.address: h.why for h in tags.build(prog, ReadOnly()).hidden}
    assert "LD %I0.3 / ST %M1" in why["%I0.3"]
    assert "LD %I0.5 / ST %M2" in why["%I0.5"]
    assert "LD %Q0.2 / ST %M3" in why["%Q0.2"]
    assert "[ %MW2 := %IW1.0 ]" in why["%IW1.0"]
    assert "[ %MW3 := %KW4 ]" in why["%KW4"]
