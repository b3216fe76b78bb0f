"""`softplc tune`: offline runs on sample files, refusals that write nothing, the figures, and
the online mode against the daemon on loopback (a tiny IL program raises the request)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from softplc.cli import main
from softplc.errors import UncertaintyError
from softplc.machines.machining import handshake, tuning
from softplc.machines.machining.mpfile import MPFile
from softplc.modbus_codec import float_to_words, words_to_float


@pytest.fixture(scope="module")
def example(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("tune")
    tuning.write_example(d, mass=22699.0, seed=3)
    return d


def test_offline_writes_the_row_2_parameters(example, tmp_path, capsys):
    out = tmp_path / "MPSet.H"
    assert main(["tune", "--dir", str(example), "--output", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert abs(res["mass"] / 22699 - 1) < 0.01 and res["row"] == 2
    tpl = (example / "MPSetTemp.H").read_bytes()
    new = out.read_bytes()
    assert len(new) == len(tpl)
    vals = MPFile(new).values()
    assert [vals[q] for q in (0, 1, 2, 11, 12, 13, 14)] == [0, 3650, 45.5, 1, 700, 20, 0]
    assert vals[21] == 0 and vals[22] == 250  # filter 2: template values


def test_offline_summary_and_light_mass(tmp_path, capsys):
    tuning.write_example(tmp_path, mass=18000.0, seed=1)
    assert main(["tune", "--dir", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "table row 1 (inert >= 0 kg)" in text and "MP2500 3550" in text
    assert "mass m = 1" in text and " ± " in text
    assert MPFile.read(tmp_path / "MPSet.H").values()[1] == 3550


def test_refusal_writes_nothing(example, tmp_path, capsys):
    s = tmp_path / "settings.txt"
    s.write_text((example / "settings.txt").read_text().replace("Acc_uncert = 0.05",
                                                                "Acc_uncert = 1e-06"))
    out = tmp_path / "MPSet.H"
    out.write_bytes(b"previous parameters")
    fig = tmp_path / "why.png"
    rc = main(["tune", "--dir", str(example), "--settings", str(s), "--output", str(out),
               "--plot", str(fig)])
    assert rc == 1
    assert "exceeds Acc_uncert" in capsys.readouterr().err
    assert out.read_bytes() == b"previous parameters"
    assert fig.read_bytes()[:4] == b"\x89PNG"  # the refused estimate is still drawn


def test_missing_file_is_a_clear_error(example, tmp_path, capsys):
    rc = main(["tune", "--dir", str(example), "--measurement", str(tmp_path / "none.dta"),
               "--dry-run"])
    err = capsys.readouterr().err
    assert rc == 1 and "none.dta: cannot read the recording" in err
    assert "Traceback" not in err


def test_plot_svg(example, tmp_path, capsys):
    # PNG: test_readme_example_output
    out = tmp_path / "fit.svg"
    assert main(["tune", "--dir", str(example), "--dry-run", "--plot", str(out)]) == 0
    svg = out.read_text()
    assert "<svg" in svg and "current [A]" in svg and "velocity [m/s]" in svg
    assert "figures written" in capsys.readouterr().err


def test_dry_run_writes_nothing(tmp_path):
    tuning.write_example(tmp_path, seed=2)
    assert main(["tune", "--dir", str(tmp_path), "--dry-run"]) == 0
    assert not (tmp_path / "MPSet.H").exists()


def test_help(capsys):
    with pytest.raises(SystemExit):
        main(["tune", "--help"])
    text = capsys.readouterr().out
    assert "--plot" in text and "--port" in text and "--example" in text


def test_words_of_a_result(example):
    res = tuning.tune_files(example / "settings.txt", example / "IMCal_.dta",
                            example / "IMMea_.dta", example / "MPSetTemp.H", None)
    w = handshake.result_words(7, res)
    assert len(w) == handshake.RESULT_END - handshake.W_ACK <= 123  # one FC 16 frame
    assert w[:4] == [7, 0, 2, 0]
    at = handshake.F_MPS - handshake.W_ACK
    assert words_to_float(w[at], w[at + 1]) == 3650.0
    at = handshake.F_MASS - handshake.W_ACK
    assert words_to_float(w[at], w[at + 1]) == pytest.approx(res.estimate.mass, rel=1e-7)
    assert float_to_words(3350.0) == (0x6000, 0x4551)  # IEEE single 0x45516000, CDAB
    err = UncertaintyError("too uncertain")
    assert handshake.error_words(8, err) == [8, 5]


def test_the_docs_example_output(tmp_path, monkeypatch, capsys):
    from docs_util import fenced, page

    text = page("docs/machines/machining-centre.md")
    cmds = fenced(text, "## The host", "sh")
    shown = fenced(text, "## The host", "text")
    monkeypatch.chdir(tmp_path)
    for line in cmds.splitlines():
        argv = line.split("#")[0].split()
        assert argv[0] == "softplc" and main(argv[1:]) == 0
        if "--example" in argv:
            capsys.readouterr()
    assert capsys.readouterr().out == shown
    assert (tmp_path / "demo" / "fit.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("edits, status", [
    ([("A_lim = 0.22", "A_lim = 2.0")], 3),  # no crossings
    ([("CHANNELID# = 29", "CHANNELID# = 28")], 2),  # channel mismatch
    ([("1, 0.0,", "1, 90000.0,"), ("2, 20000.0,", "2, 95000.0,")], 6),  # no row for 22.7 t
])
def test_every_refusal_leaves_the_parameters_untouched(example, tmp_path, edits, status):
    from softplc.errors import MassEstimationError

    text = (example / "settings.txt").read_text()
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    s = tmp_path / "settings.txt"
    s.write_text(text)
    out = tmp_path / "MPSet.H"
    with pytest.raises(MassEstimationError) as e:
        tuning.tune_files(s, example / "IMCal_.dta", example / "IMMea_.dta",
                          example / "MPSetTemp.H", out)
    assert e.value.status == status
    assert not out.exists() and not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("answer, written", [("y\n", True), ("n\n", False), ("", False)])
def test_confirm(tmp_path, monkeypatch, capsys, answer, written):
    import io

    tuning.write_example(tmp_path, seed=5)
    monkeypatch.setattr("sys.stdin", io.StringIO(answer))
    rc = main(["tune", "--dir", str(tmp_path), "--confirm"])
    assert (rc == 0) == written and (tmp_path / "MPSet.H").exists() == written
    captured = capsys.readouterr()
    assert "table row 2" in captured.err
    if not written:
        assert "not confirmed; nothing written" in captured.err


def test_macro_geometry_example(tmp_path, capsys):
    assert main(["tune", "--example", str(tmp_path), "--geometry", "macro", "--mass",
                 "18000", "--no-noise"]) == 0
    assert main(["tune", "--dir", str(tmp_path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out.split("\n", 4)[-1])
    assert abs(res["mass"] / 18000 - 1) < 5e-4 and res["row"] == 1
    assert res["acceleration"] == pytest.approx(0.4, rel=1e-3)


def test_two_example_runs_give_identical_files(tmp_path):
    a = tuning.write_example(tmp_path / "a", seed=9)
    b = tuning.write_example(tmp_path / "b", seed=9)
    for kind in a:
        assert a[kind].read_bytes() == b[kind].read_bytes(), kind
    c = tuning.write_example(tmp_path / "c", seed=10)
    assert c["measurement"].read_bytes() != a["measurement"].read_bytes()
