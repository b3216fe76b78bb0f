"""`softplc cut` from any folder (issue 33): the default machine configuration is the shipped
one wherever the command runs, and a bad --machine is refused before the cut, not after."""

from __future__ import annotations

from pathlib import Path

from softplc.cli import build_parser, main

PIECE = Path(__file__).resolve().parents[2] / "ladder_programs" / "pieces" / "cuadrado.toml"


def test_the_default_machine_is_found_from_another_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = build_parser("cut").parse_args(["cut", "piece.dxf"])
    machine = Path(args.machine)
    assert machine.is_absolute() and machine.is_file()
    assert machine.name == "cutting_table.toml"


def test_a_missing_machine_file_is_refused_before_connecting(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    # port 9 on loopback: nothing is ever asked of it, the --machine check comes first
    rc = main(["cut", str(PIECE), "--port", "9", "--trace", "cut.csv",
               "--machine", "missing.toml"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "--machine" in err and "missing.toml" in err
    assert "cannot reach" not in err
