"""The trace player (softplc.verify.player) and `softplc replay`: a counterexample of
`softplc verify --cex` played scan by scan in the engine, forward and back."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from softplc.cli import main
from softplc.errors import SoftPLCError
from softplc.plc import PLC
from softplc.verify.player import COLD, HOLDS, VIOLATED, TracePlayer, highlight
from softplc.verify.replay import MAX_CEX_SCANS, read_cex

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"
DEFECT = [str(LP / "star_delta_defect.il"), "--config", str(LP / "star_delta.toml")]
OVERLOAD = "overload: every contactor off in the same scan"  # star_delta.req.toml


@pytest.fixture(scope="module")
def cex_files(tmp_path_factory) -> dict[str, Path]:
    """The shipped requirements' counterexample (one scan) and a longer one: the delta
    contactor is reached after the star time with a free scan period (several scans)."""
    d = tmp_path_factory.mktemp("cex")
    shipped, delta = d / "shipped.json", d / "delta.json"
    assert main(["verify", *DEFECT, "--require", str(LP / "star_delta.req.toml"), "-q",
                 "--depth", "5", "--cex", str(shipped)]) == 2
    assert main(["verify", *DEFECT, "--require-expr", "never %Q0.2", "--scan-period",
                 "10ms:1s", "--depth", "12", "-q", "--cex", str(delta)]) == 2
    return {"shipped": shipped, "delta": delta}


def player(path: Path, i: int = 0) -> TracePlayer:
    item = read_cex(path)["counterexamples"][i]
    return TracePlayer(lambda: PLC.from_file(DEFECT[0], config=DEFECT[2], devices=False), item)


def test_the_shipped_requirement_is_violated_at_the_reported_scan(cex_files):
    p = player(cex_files["shipped"])
    try:
        assert p.requirement == OVERLOAD
        assert p.violated_at == p.total == 1  # the verifier's shortest counterexample
        assert p.frame()["status"] == COLD and p.frame()["inputs"] == {}
        p.goto(p.total)
        f = p.frame()
        assert f["status"] == VIOLATED and f["inputs"]["%I0.2"] == 0  # the relay is open
        values = {v["object"]: v["engine"] for v in f["values"]}
        assert values["%I0.2"] == 0 and values["%Q0.0"] == 1  # the motor runs anyway
        assert all(v["agree"] for v in f["values"])  # engine = the verifier's model
    finally:
        p.close()


def test_forward_and_back_give_the_same_scans(cex_files):
    p = player(cex_files["delta"])
    try:
        assert p.total > 2 and p.violated_at == p.total
        forward = []
        for n in range(p.total + 1):
            p.goto(n)
            forward.append(p.frame())
        assert [f["status"] for f in forward] == [COLD] + [HOLDS] * (p.total - 1) + [VIOLATED]
        assert forward[-1]["values"] == [{"object": "%Q0.2", "engine": 1, "model": 1,
                                          "agree": True}]
        scans = p.plc.scan_count
        for n in reversed(range(p.total + 1)):  # back: snapshots restored, no scan run
            p.goto(n)
            assert p.frame() == forward[n]
            assert p.plc.scan_count == n
        assert scans == p.total
        p.goto(p.total + 5)  # clamped
        assert p.position == p.total
        assert [r["status"] for r in p.history()] == [f["status"] for f in forward[1:]]
        assert p.position == p.total  # history() leaves the position where it was
    finally:
        p.close()


def test_the_requirement_objects_are_highlighted_in_the_rungs(cex_files):
    p = player(cex_files["delta"])
    try:
        p.goto(p.total)
        svgs = p.rung_svgs()
        assert len(svgs) == len(p.plc.ast.rungs)
        labels = re.findall(r'<text class="req"[^>]*>([^<]*)</text>', "".join(svgs))
        assert labels and set(labels) == {"%Q0.2"}  # the coil and each contact of it
    finally:
        p.close()


def test_highlight_marks_only_the_named_labels():
    svg = '<svg><text x="1">%I0.2</text><text x="2">%I0.20</text><text>%Q0.0</text></svg>'
    out = highlight(svg, ["%I0.2"])
    assert out.count('class="req"') == 1 and '<text class="req" x="1">%I0.2</text>' in out
    assert highlight(svg, []) == svg
    box = '<text x="3" font-weight="bold">%TM0</text>'
    assert 'class="req"' in highlight(box, ["%TM0.Q"])  # the block of a field
    assert 'class="req"' not in highlight(box, ["%TM01.Q", "%I0.2"])


def test_replay_command_prints_every_scan(cex_files, capsys):
    assert main(["replay", *DEFECT, str(cex_files["delta"])]) == 0
    out = capsys.readouterr().out
    lines = [x for x in out.splitlines() if x.lstrip().startswith("scan")]
    assert len(lines) == len(read_cex(cex_files["delta"])["counterexamples"][0]["scans"])
    assert lines[-1].endswith("VIOLATED") and "%Q0.2=1" in lines[-1]
    assert all(x.endswith("holds") for x in lines[:-1])


def test_run_replay_is_the_same_replay(cex_files, capsys):
    """`softplc run PROGRAM --replay CEX.json` (the issue's spelling) replays instead of
    starting the daemon: no Modbus server; with --web off the table."""
    assert main(["run", *DEFECT, "--replay", str(cex_files["shipped"]), "--web", "off"]) == 0
    out = capsys.readouterr().out
    assert OVERLOAD in out and "listening" not in out
    assert out.rstrip().endswith("VIOLATED") and "%I0.2=0 %Q0.0=1" in out


def test_run_replay_refuses_the_daemons_options(cex_files, capsys):
    """A daemon option with --replay would do nothing: refused, named, nothing played."""
    assert main(["run", *DEFECT, "--replay", str(cex_files["shipped"]), "--web", "off",
                 "--state", "plc.state", "--port", "1502"]) == 1
    err = capsys.readouterr().err
    assert "--port, --state would have no effect" in err and "Traceback" not in err


def test_a_trace_the_engine_does_not_break_exits_1(cex_files, tmp_path, capsys):
    data = json.loads(cex_files["delta"].read_text())
    data["counterexamples"][0]["scans"].pop()  # without its last scan: no violation
    short = tmp_path / "short.json"
    short.write_text(json.dumps(data))
    assert main(["replay", *DEFECT, str(short)]) == 1
    out = capsys.readouterr().out
    assert "violated in the engine at no scan" in out and "VIOLATED" not in out


@pytest.mark.parametrize("text, says", [
    ("{", "not a counterexample file"),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"inputs": {"%I0.0": NaN}}]}]}', "not a finite number"),
    ('{"format": "other"}', "written by softplc verify"),
    ('{"format": "softplc-cex/1", "counterexamples": []}', "no counterexample"),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2"}]}',
     '"scans"'),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"inputs": {"%I0.0": "x"}}]}]}', "scan 1"),
    ("[" * 100_000, "not a counterexample file"),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"inputs": {}, "values": [1]}]}]}', '"values" maps'),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"values": {}}]}]}', '"inputs" maps'),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"inputs": {}, "values": {"%ZZ1": 1}}]}]}', "%ZZ1"),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never %Q0.2", '
     '"scans": [{"inputs": {"period_ms": 1e308}}]}]}', "scan 1"),
    ('{"format": "softplc-cex/1", "counterexamples": [{"check": "never (((", '
     '"scans": [{"inputs": {}}]}]}', "never ((("),
])
def test_bad_counterexample_files_get_a_clear_error(tmp_path, capsys, text, says):
    bad = tmp_path / "bad.json"
    bad.write_text(text)
    assert main(["replay", *DEFECT, str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("softplc: error: ") and says in err and "Traceback" not in err


def test_too_many_scans_and_bad_addresses_are_refused(tmp_path, capsys):
    long = tmp_path / "long.json"
    long.write_text(json.dumps({"format": "softplc-cex/1", "counterexamples": [
        {"check": "never %Q0.2", "scans": [{"inputs": {}}] * (MAX_CEX_SCANS + 1)}]}))
    with pytest.raises(SoftPLCError, match=f"at most {MAX_CEX_SCANS}"):
        read_cex(long)
    addr = tmp_path / "addr.json"
    addr.write_text(json.dumps({"format": "softplc-cex/1", "counterexamples": [
        {"check": "never %Q0.2", "scans": [{"inputs": {"%ZZ9": 1}}]}]}))
    assert main(["replay", *DEFECT, str(addr)]) == 1
    err = capsys.readouterr().err
    assert "never %Q0.2" in err and "%ZZ9" in err and "Traceback" not in err
    assert main(["replay", *DEFECT, str(addr), "--index", "2"]) == 1
    assert "counterexamples 1 to 1" in capsys.readouterr().err


def test_the_docs_page_example_runs_as_written(tmp_path, capsys, monkeypatch):
    """docs/replay.md: its commands, run from the repository, print what the page shows
    (the header lines; the last scan breaks the requirement)."""
    page = (ROOT / "docs" / "replay.md").read_text()
    start = page.index("## Watching a counterexample")
    bash = re.search(r"```bash\n(.*?)```", page[start:], re.S)[1].replace("\\\n", " ")
    verify, replay = (shlex.split(line)[1:] for line in bash.strip().splitlines())
    shown = re.search(r"```text\n(.*?)```", page[start:], re.S)[1].splitlines()
    monkeypatch.chdir(ROOT)
    cex = str(tmp_path / "cex.json")
    assert main([cex if a == "cex.json" else a for a in verify]) == 2
    capsys.readouterr()
    assert main([cex if a == "cex.json" else a for a in replay]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[:2] == shown[:2]
    assert out[-1].split(": ")[0] == shown[-1].split(": ")[0] and out[-1].endswith("VIOLATED")
