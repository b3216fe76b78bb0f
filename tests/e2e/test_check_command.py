"""`softplc check`: the command-line face of the parser and compiler."""

from __future__ import annotations

import json

from softplc.cli import main as softplc
from softplc.il.parser import parse


def test_errors_are_listed_with_positions(tmp_path, capsys):
    prog = tmp_path / "bad.il"
    prog.write_text("LDX %M0\nST %Q0.0\nLD 1\nST %I0.0\nLD %M999\n")
    assert softplc(["check", str(prog)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"{prog}:1:1: unknown instruction 'LDX'")
    assert err[1].startswith(f"{prog}:4:1: cannot write %I0.0")
    assert err[2].startswith(f"{prog}:5:4: '%M999' is beyond the controller profile")
    assert err[-1] == "3 errors"


def test_json_errors(tmp_path, capsys):
    prog = tmp_path / "bad.il"
    prog.write_text("LD 1\n[ %MW0 := %MF2 ]\n")
    assert softplc(["check", str(prog), "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    (e,) = out["errors"]
    assert out["ok"] is False and (e["line"], e["column"], e["text"]) == (2, 3, "%MW0")
    assert "INT_TO_REAL" in e["expected"]


def test_summary_rungs_json_format_and_python(capsys):
    args = ["check", "ladder_programs/drawing_table.il", "--config",
            "ladder_programs/drawing_table.toml"]
    assert softplc([*args, "--rungs"]) == 0
    out = capsys.readouterr().out
    assert "OK - 30 rungs" in out and "rung   9" in out and "INICIO > 100 while idle" in out
    assert softplc([*args, "--json"]) == 0
    rungs = json.loads(capsys.readouterr().out)["rungs"]
    assert len(rungs) == 30 and rungs[0]["title"].startswith("PULSOS")
    assert softplc([*args, "--format"]) == 0
    text = capsys.readouterr().out  # the program only: `> new.il` gives a program
    original = parse(open("ladder_programs/drawing_table.il").read())
    again = parse(text)
    assert [r.instructions for r in again.rungs] == [r.instructions for r in original.rungs]
    assert softplc([*args, "--python"]) == 0
    assert "def _main(" in capsys.readouterr().out


MESSY = """\
(* Motor latch, first line of the header *)
(*   %I0.0 start, %I0.1 stop *)


SECTION 0
(*RUNG: latch*)
ld %i0.0   (* start button *)
or %Q0.0
andn %I0.1
st %Q0.0
(* a comment over
   two lines *)
ld 1
[%MW0:=%MW1+1]
LD %M0
IN %TM0
"""


def test_format_is_a_formatter(tmp_path, capsys):
    """Formatted program alone on stdout, comments kept, no --config needed (%TM0 is not
    configured), the same rungs; --in-place rewrites the file once, CRLF kept."""
    prog = tmp_path / "messy.il"
    prog.write_text(MESSY)
    assert softplc(["check", "--format", str(prog)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert out.startswith("(* Motor latch, first line of the header *)\n"
                          "(*   %I0.0 start, %I0.1 stop *)\n\nSECTION     0\n")
    assert "LD    %I0.0  (* start button *)\n" in out
    assert "(* a comment over\n   two lines *)\n" in out
    assert "[ %MW0 := %MW1 + 1 ]\n" in out
    before, after = parse(MESSY), parse(out)
    assert [(r.title, r.instructions) for r in after.rungs] == \
        [(r.title, r.instructions) for r in before.rungs]
    crlf = tmp_path / "crlf.il"
    crlf.write_bytes(MESSY.replace("\n", "\r\n").encode())
    assert softplc(["check", "--format", "--in-place", str(crlf)]) == 0
    assert capsys.readouterr() == ("", f"{crlf}: formatted\n")
    assert crlf.read_bytes() == out.replace("\n", "\r\n").encode()
    assert softplc(["check", "--in-place", str(crlf)]) == 0
    assert capsys.readouterr() == ("", f"{crlf}: already formatted\n")


def test_format_refuses_a_bad_program_and_changes_nothing(tmp_path, capsys):
    prog = tmp_path / "bad.il"
    prog.write_text("LD %I0.0\nSTX %Q0.0\n")
    assert softplc(["check", "--format", "--in-place", str(prog)]) == 1
    out, err = capsys.readouterr()
    assert out == "" and f"{prog}:2:1: unknown instruction 'STX'" in err
    assert prog.read_text() == "LD %I0.0\nSTX %Q0.0\n"
    # with --config, the full check runs too
    cfg = tmp_path / "c.toml"
    cfg.write_text("")
    prog.write_text("LD %M0\nIN %TM0\n")
    assert softplc(["check", "--format", str(prog), "--config", str(cfg)]) == 1
    out, err = capsys.readouterr()
    assert out == "" and "timer %TM0 is used but not configured" in err


def test_missing_file(capsys):
    assert softplc(["check", "no/such/program.il"]) == 1
    assert "no/such/program.il: no such file (program)" in capsys.readouterr().err
    assert softplc(["check", "no/such/program.il", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is False and out["errors"][0]["file"] == "no/such/program.il"
    assert "no such file" in out["errors"][0]["message"]


def test_command_line_defaults_match_the_modules_they_stand_for():
    """Constants the commands repeat so that `softplc --help` need not import them."""
    from softplc import fleet
    from softplc.commands import _args
    from softplc.commands import fleet as fleet_command
    from softplc.modbus.regmap import DEFAULT_PORT

    assert _args.DEFAULT_MODBUS_PORT == DEFAULT_PORT
    assert fleet_command.MAX_CONTROLLERS == fleet.MAX_CONTROLLERS


def test_help_does_not_import_the_plc_or_pydantic():
    """`softplc --help` stays fast: softplc.PLC is imported on first use (PEP 562), the
    commands import the compiler, Modbus and pydantic when they run; the `tune` command's
    parser takes its names from a light module, not the tuning code and numpy."""
    import subprocess
    import sys

    code = ("import sys, softplc.cli, softplc\n"
            "softplc.cli.build_parser()\n"
            "print(sorted(m for m in ('softplc.plc', 'softplc.modbus', 'softplc.compiler',"
            " 'pydantic', 'numpy', 'softplc.machines.machining.tuning',"
            " 'softplc.machines.machining.retune') if m in sys.modules))\n"
            "assert softplc.PLC.__name__ == 'PLC'\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
