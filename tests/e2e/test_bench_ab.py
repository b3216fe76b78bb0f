"""The A/B benchmark runner (tools/bench_cpu_ab.py): sides from a git revision or a
checkout path, runs alternating in child processes importing their own side's softplc, the
best / median table, and clear errors for a bad side. No time threshold is asserted."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
TOOLS = ROOT / "tools"
sys.path.insert(0, str(TOOLS))

import bench_cpu_ab as ab  # noqa: E402

needs_git = pytest.mark.skipif(
    subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "HEAD"],
                   capture_output=True).returncode != 0, reason="not a git repository")

# A tiny figure: where the child's softplc comes from, and a number.
PROBE = ("import json, pathlib, softplc; here = pathlib.Path(softplc.__file__).resolve(); "
         "print('noise'); print(json.dumps({'own_tree': float(here.is_relative_to("
         "pathlib.Path.cwd().resolve())), 'n': 2.5}))")
KEYS = (("own_tree", "softplc from the side's tree", True), ("n", "a figure", False),
        ("absent", "a figure one side lacks", False))
ROW = re.compile(r"^  (.+?) +(\S+) / +(\S+) +(\S+) / +(\S+) +(\S+)$")


@needs_git
def test_runner_against_head_alternates_and_prints_best_median_ratio() -> None:
    order: list[str] = []

    def run(side: ab.Side) -> dict[str, Any]:
        order.append(side.label)
        return ab.child(side, ["-c", PROBE])

    text = ab.compare("HEAD", 2, run, KEYS, "Probe A/B")
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short=7", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert order == [f"HEAD ({head})", ab.THIS, ab.THIS, f"HEAD ({head})"]  # A B, B A
    lines = text.splitlines()
    assert lines[0] == "Probe A/B, 2 alternating runs each"
    assert lines[1].startswith(f"  A: HEAD ({head}); B: this checkout; load average ")
    assert lines[2].split() == ["figure", "A", "best", "/", "median", "B", "best", "/",
                                "median", "B", "vs", "A"]
    rows = {m.group(1): m.groups()[1:] for m in map(ROW.match, lines[3:5]) if m}
    # each side's child imported softplc from its own tree (HEAD's export, this checkout)
    assert rows["softplc from the side's tree"] == ("1.00", "1.00", "1.00", "1.00", "1.000x")
    assert rows["a figure"] == ("2.50", "2.50", "2.50", "2.50", "1.000x")
    assert lines[5].split()[-3:] == ["-", "-", "-"] and len(lines) == 6


def test_scan_cost_cli_of_two_sides(capsys: pytest.CaptureFixture[str]) -> None:
    """The command's table; side A this checkout given as a path (a revision's export is
    the test above's): both sides' children load the checkout's compiled modules."""
    assert ab.main([str(ROOT), "--rounds", "1", "--scans", "20"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("plc.scan() A/B") and len(out) == 3 + len(ab.SCAN_KEYS)
    for line, (_, label, _) in zip(out[3:], ab.SCAN_KEYS, strict=True):
        m = ROW.match(line)
        assert m and m.group(1) == label, line
        best_a, med_a, best_b, med_b = map(float, m.groups()[1:5])
        assert 0 < best_a <= med_a and 0 < best_b <= med_b
        # lower is better: the ratio is A's best over B's (of the unrounded figures)
        assert float(m.group(6).rstrip("x")) == pytest.approx(best_a / best_b, rel=0.02)


def test_bad_sides_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ab.ABError, match="'no-such-rev': neither a checkout directory nor "
                                         "a git revision"):
        ab.compare("no-such-rev", 1, lambda side: {}, KEYS, "x")
    with pytest.raises(ab.ABError, match="a directory without softplc/, not a checkout"):
        ab.compare(str(tmp_path), 1, lambda side: {}, KEYS, "x")
    with pytest.raises(ab.ABError, match="--rounds"):
        ab.compare(str(ROOT), 0, lambda side: {}, KEYS, "x")


def test_a_failing_or_silent_child_names_its_side() -> None:
    side = ab.Side("HEAD~9 (abcdef0)", ROOT)
    with pytest.raises(ab.ABError, match=r"(?s)HEAD~9 \(abcdef0\): the benchmark failed.*boom"):
        ab.child(side, ["-c", "raise SystemExit('boom')"])
    with pytest.raises(ab.ABError, match="no JSON object"):
        ab.child(side, ["-c", "print('[1, 2]')"])


@pytest.mark.parametrize("argv", [
    ["bench_cpu_ab.py", "no-such-rev"],
    ["bench_engine.py", "--quick", "--against", "no-such-rev"],
    ["bench_sim_ab.py", "no-such-rev", "--benches", "mass"],
    ["bench_build.py", "--tree", "no-such-rev"],
    ["bench_modbus_c.py", "--baseline", "no-such-rev"],
])
def test_tools_report_a_bad_revision_without_traceback(argv: list[str]) -> None:
    r = subprocess.run([sys.executable, str(TOOLS / argv[0]), *argv[1:]],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout == ""
    assert "'no-such-rev': neither a checkout directory nor a git revision" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_checkout_path_runs_from_a_copy_of_its_files(tmp_path: Path) -> None:
    """A side given as a directory (here not a git checkout) runs from a copy of its files
    as they are, environments and caches left out."""
    co = tmp_path / "co"
    (co / "softplc").mkdir(parents=True)
    (co / "softplc" / "__init__.py").write_text("MARK = 7.0\n")
    (co / ".venv").mkdir()
    (co / ".venv" / "big").write_text("x")
    probe = ("import json, os, softplc; print(json.dumps({'mark': softplc.MARK, "
             "'venv': float(os.path.exists('.venv'))}))")
    with ab.sides([str(co)]) as (side,):
        assert side.label == str(co) and side.root != co
        assert ab.child(side, ["-c", probe]) == {"mark": 7.0, "venv": 0.0}
    assert not side.root.exists()  # the copy goes with the block
