"""Smoke test of the benchmarks: they run and return well-formed figures.

Never asserts a time threshold (CONTRIBUTING: tests check behaviour, not speed)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"
sys.path.insert(0, str(TOOLS))

import bench_engine  # noqa: E402
import bench_floor  # noqa: E402
import bench_peers  # noqa: E402
from peers.programs import chain_program, mixed_program, to_stl  # noqa: E402

from softplc.plc import PLC  # noqa: E402


def _positive(x: object) -> bool:
    return isinstance(x, float) and math.isfinite(x) and x > 0


def test_floor_benchmark_tiny() -> None:
    res = bench_floor.run(number=20, repeat=1)
    assert {k.split(", ")[0] for k in res} == {"virtual", "real"} and len(res) == 8
    for name, r in res.items():
        assert all(_positive(r[k]) for k in ("main", "engine", "plc")), name


def test_engine_benchmark_tiny(tmp_path: Path) -> None:
    (tmp_path / "good.il").write_text("LD %M0\nANDN %M1\nST %Q0.0\n")
    (tmp_path / "bad.il").write_text("LD %M0\nFROB %M1\n")
    res = bench_engine.run(tiny=True, programs_dir=tmp_path)
    b = res["boolean"]
    assert b["instructions"] == 40
    for key in ("main_us", "scan_us", "main_ns_per_instr", "scan_ns_per_instr",
                "floor_ns_per_instr"):
        assert _positive(b[key]), key
    assert res["mixed40"]["rungs"] == 40 and _positive(res["mixed40"]["scan_us"])
    by_name = {p["program"]: p for p in res["programs"]}
    assert set(by_name) == {"good.il", "bad.il"}
    assert by_name["good.il"]["instructions"] == 3 and _positive(by_name["good.il"]["scan_us"])
    assert "error" in by_name["bad.il"] and "main_us" not in by_name["bad.il"]
    text = bench_engine.report(res)
    assert "bad.il" in text and "error" in text
    assert len(bench_engine.verdicts(res)) == 4


def test_generated_programs_have_the_announced_size() -> None:
    plc = PLC.from_source(chain_program(3))
    assert plc.program.instruction_count == 15 and len(plc.rungs) == 3
    text, cfg = mixed_program(40)
    assert len(PLC.from_source(text, cfg).rungs) == 40
    stl, n = to_stl(chain_program(2))
    assert n == 12 and stl.count("U(") == 2 and stl.startswith("ORGANIZATION_BLOCK OB 1")


def test_peer_table_ratios_and_unavailable_peers() -> None:
    res = {
        "pyrung": {"unavailable": "ModuleNotFoundError: No module named 'pyrung'"},
        "awlsim": {"boolean": {"label": "b", "il_instructions": 10, "stl_instructions": 12,
                               "softplc_us": 2.0, "awlsim_us": 200.0,
                               "softplc_instr_per_s": 5e6, "awlsim_instr_per_s": 6e4,
                               "ratio": 100.0},
                   "words": {"label": "w", "error": "AwlSimError: x"}},
        "modbus": {"softplc": {q: {n: {"requests_per_s": 900.0, "p50_ms": 1.0, "p99_ms": 2.0,
                                       "errors": 0} for n in ("1", "8")}
                               for q in ("fc3", "fc16")},
                   "pymodbus": {q: {n: {"requests_per_s": 1000.0, "p50_ms": 1.0,
                                        "p99_ms": 2.0, "errors": 0} for n in ("1", "8")}
                                for q in ("fc3", "fc16")},
                   "libmodbus": {"unavailable": "gcc not installed"}},
    }
    rows = bench_peers.rows(res)
    assert rows[0]["note"].startswith("unavailable: ModuleNotFoundError")
    mb = [r for r in rows if r["peer"] == "pymodbus"]
    assert len(mb) == 4 and all(r["advantage"] == pytest.approx(0.9) and r["met"] for r in mb)
    assert any(r["peer"] == "libmodbus" and "gcc" in r["note"] for r in rows)
    assert "unavailable" in bench_peers.report(res)


def test_bench_wordops_reports_every_case() -> None:
    import bench_wordops
    res = bench_wordops.run(lines=10, number=5, repeat=1)
    assert set(res["ns_per_line"]) == set(bench_wordops.CASES) | {"add16 floor", "add16 list"}
    assert all(v > 0 for v in res["ns_per_line"].values())
    assert "counter_blk" in bench_wordops.report(res)


def test_bench_rejects_unknown_section() -> None:
    r = subprocess.run([sys.executable, str(TOOLS / "bench.py"), "--sections", "engine,warp"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "unknown section" in r.stderr


def test_cutting_benchmark_small() -> None:
    import bench_cutting

    from softplc.machines.cutting import load_piece

    square = Path(__file__).resolve().parents[2] / "ladder_programs" / "pieces" / "cuadrado.toml"
    r = bench_cutting.run(speed=20.0, piece_file=square)
    assert r["segments"] == len(load_piece(square, speed=20.0).segments())
    for key in ("simulated_s", "wall_s", "cpu_s", "speedup", "speedup_cpu"):
        assert _positive(r[key]), key
    assert "Cutting table" in bench_cutting.report(r)


def test_compile_benchmark_small(capsys: pytest.CaptureFixture[str]) -> None:
    import bench_compile

    from softplc.il.parser import parse

    text = bench_compile.program(30)
    assert text.count("\n") == 30 * 5 + 1
    assert len(parse(text).rungs) == 30  # END closes the last one
    assert bench_compile.main(["--rungs", "30", "--repeat", "1", "--no-count"]) == 0
    out = capsys.readouterr().out
    assert "30 rungs (151 lines)" in out and "RSS loaded" in out


@pytest.mark.parametrize("fc", [3, 16])
def test_c_load_generator_against_the_server(tmp_path: Path, fc: int) -> None:
    """The C load generator of bench_modbus_c.py: a short run gets replies, no error."""
    import shutil

    import bench_modbus_c

    from softplc.modbus import ModbusImage, ServerThread
    from softplc.runtime.memory import MemoryImage

    if not shutil.which("gcc"):
        pytest.skip("gcc not installed")
    exe = bench_modbus_c.build_load(tmp_path)
    th = ServerThread(ModbusImage(MemoryImage()), "127.0.0.1", 0).start()
    try:
        qty = 10 if fc == 3 else 100
        r = subprocess.run([str(exe), str(th.port), "4", "0.3", str(fc), str(qty), "100"],
                           capture_output=True, text=True, timeout=20)
    finally:
        th.stop()
    words = r.stdout.split()
    assert r.returncode == 0 and words[0] == "replies" and words[2] == "errors"
    assert int(words[1]) > 0 and int(words[3]) == 0
    assert th.stats.requests >= int(words[1]) and th.stats.exceptions == 0


def test_startup_benchmark_one_command() -> None:
    """One short command line (the run command's help), one run: a CPU figure from the
    child's rusage, and the report's row."""
    import bench_startup

    label, args = next(c for c in bench_startup.COMMANDS if c[1] == ("run", "--help"))
    res = bench_startup.run(runs=1, commands=((label, args),))
    assert set(res) == {label} and res[label]["argv"] == ["run", "--help"]
    assert _positive(res[label]["best_s"]) and res[label]["best_s"] == res[label]["median_s"]
    assert label in bench_startup.report(res)
    with pytest.raises(ValueError):
        bench_startup.run(runs=0)


def test_startup_benchmark_stops_a_command_at_its_line(tmp_path) -> None:
    """A command line with a last line (`softplc run`'s banner) is stopped once it prints
    it, and one that ends without printing it is an error, not a figure."""
    import sys

    import bench_startup

    waits = [sys.executable, "-c", "import time; print('ready', flush=True); time.sleep(600)"]
    assert _positive(bench_startup.cpu_of(waits, tmp_path, "ready"))  # not 600 s later
    with pytest.raises(RuntimeError, match="without printing 'ready'"):
        bench_startup.cpu_of([sys.executable, "-c", "print('done')"], tmp_path, "ready")


def test_bench_floor_parts_removes_each_part_it_names() -> None:
    """Every edit finds its text in the generated scan (else the tool exits), and each
    variant still runs."""
    import bench_floor_parts
    res = bench_floor_parts.run(number=20, repeat=1)
    assert set(res) == {"main", "full", *bench_floor_parts.PARTS}


_LOOP_CHILD = r"""
import os
import sys
import instr_count
def work(k):
    s = 0
    for i in range(k):
        s += i
    return s
k = int(sys.argv[2])
instr_count.start()
for _ in range(int(sys.argv[1])):
    work(k)
sys.stdout.flush()
os._exit(0)  # no interpreter teardown: 20 M instructions, instrumented, in every run
"""


def test_instruction_count_is_per_iteration_and_repeatable(tmp_path: Path) -> None:
    """Issue 32 item 6: the count under callgrind grows by the same amount for each 50 more
    iterations of the child's loop (the start-up cancels out in a difference), and a run
    repeated gives the same total, whatever the machine's load. Four callgrind runs (each
    about 2 s of CPU, nearly all of it Python's start-up under valgrind)."""
    import instr_count

    if not instr_count.available():
        pytest.skip(instr_count.MISSING)

    def run(n: int, name: str) -> tuple[int, int]:
        return instr_count._run(_LOOP_CHILD, n, tmp_path / name, ("100",))

    (a, ca), (b, cb), (c, _) = run(10, "a"), run(60, "b"), run(110, "c")
    again = run(60, "again")[0]
    assert b - a > 50 * 1000  # 50 iterations of a 100-step loop: thousands of instructions
    assert abs((c - b) - (b - a)) < 0.02 * (b - a)  # per iteration: linear in the count
    assert abs(again - b) < 0.01 * (b - a)  # repeatable to 1 % of the measured work
    assert cb - ca == 0  # the loop reads no clock


def test_plant_benchmark_tiny(tmp_path: Path) -> None:
    import bench_plant

    from softplc.plant import Plant

    path = bench_plant.build(tmp_path, 3, 20)
    per_cpu, per_wall, scans = bench_plant.measure(path, 0.5)
    assert _positive(per_cpu) and _positive(per_wall) and scans == 3 * 50
    plant = Plant.from_file(path)  # the generated programs exchange on the link
    plant.run(1.0)
    assert plant["master:%SW111"] == 0b11
    plant.close()
