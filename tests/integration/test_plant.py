"""The example plant (ladder_programs/plant: a line controller, a filler and a capper on the
Remote Link, the belt they share) in one process on one virtual clock: the line works, the
run is deterministic, and the faults of issue 35 are seen and handled."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.cli import main
from softplc.errors import PlantStateError
from softplc.plant import Plant, PlantError
from softplc.runtime.exch import ERR_TIMEOUT as ERR_EXCH_TIMEOUT
from softplc.runtime.remotelink import ERR_NONE, ERR_TIMEOUT, MISSES

PLANT = Path(__file__).resolve().parents[2] / "ladder_programs" / "plant" / "plant.toml"
LINK_CYCLE_S = 0.020  # plant.toml: links.line.cycle
FILLER, CAPPER = 1, 2  # their Remote Link addresses (bits 0 and 1 of the master's %SW111)


@pytest.fixture
def line(plant_from_file) -> Plant:
    """The line switched on and run until boxes come out."""
    p = plant_from_file(PLANT)
    p["master:%I0.0"] = 1
    assert p.run_until(lambda p: p["master:%MW0"] >= 2, timeout=30.0)
    return p


def link_cycles_until(p: Plant, condition, limit: int = 20) -> int:
    """Run the plant link cycle by link cycle (with the scans of the same instant) until
    `condition(p)`; how many cycles it took."""
    link = p.links["line"]
    start = link.cycles
    while link.cycles - start < limit:
        done = link.cycles
        assert p.run_until(lambda p, done=done: link.cycles > done, timeout=1.0)
        if condition(p):
            return link.cycles - start
    raise AssertionError(f"not within {limit} link cycles")


def test_the_line_fills_caps_and_delivers_every_box(line: Plant):
    line.run(60.0)
    belt = line.devices["belt"]
    out, filled, capped = line["master:%MW0"], line["master:%MW1"], line["master:%MW2"]
    # every box that left was filled and capped; at most the two on the belt are not yet
    assert out == belt.delivered and filled >= capped >= out and belt.fed - out <= 3
    assert out >= 18  # a box every 3 s
    assert line["master:%SW111"] == 0b11 and line["master:%SW112"] == ERR_NONE
    assert line["filler:%MW0"] == filled and line["capper:%MW0"] == capped


def test_the_figures_the_docs_give(plant_from_file):
    p = plant_from_file(PLANT)  # docs/plant.md: the line on, 60 s of plant time
    p["master:%I0.0"] = 1
    p.run(60.0)
    assert (p["master:%MW0"], p["master:%MW1"], p["master:%MW2"]) == (18, 19, 19)


def test_the_master_sees_the_photo_eyes_its_stations_see(line: Plant):
    seen = 0
    for _ in range(500):
        line.scan()
        assert line["master:%I0.1"] == line["filler:%I0.0"] == line["belt:at_fill"]
        seen += line["master:%I0.1"]
    assert seen  # a box stood at the filler meanwhile


def test_a_plant_run_is_the_same_every_time(plant_from_file):
    def run() -> dict:
        p = plant_from_file(PLANT)
        p["master:%I0.0"] = 1
        p.run(20.0)
        p.faults.kill("capper")
        p.run(1.0)
        p.faults.restart("capper")
        p.run(5.0)
        return p.snapshot()

    assert run() == run()


def test_a_killed_peer_is_seen_within_misses_cycles_and_the_master_stops_the_belt(line):
    line.faults.kill("capper")
    n = link_cycles_until(line, lambda p: not p["master:%SW111"] >> (CAPPER - 1) & 1)
    assert n <= MISSES  # the stated figure: MISSES link cycles (docs/plant.md)
    assert line["master:%SW112"] == ERR_TIMEOUT
    line.scan(2)  # the master's program reacts at its next scan
    assert not line["master:%Q0.0"] and line["master:%Q0.3"]  # belt off, fault lamp
    assert line["master:%SW111"] & 1  # the filler is still there


def test_a_restarted_peer_rejoins_without_restarting_the_master(line: Plant):
    master_scans = line.plc("master").scan_count
    line.faults.kill("capper")
    line.run(1.0)
    with pytest.raises(PlantStateError, match="kill it first"):
        line.faults.restart("filler")
    line.faults.restart("capper")
    assert line["capper:%MW0"] == 0  # a cold start: its count starts again
    n = link_cycles_until(line, lambda p: p["master:%SW111"] == 0b11)
    assert n <= 2
    delivered = line["master:%MW0"]
    line.run(20.0)
    assert line["master:%MW0"] > delivered and not line["master:%Q0.3"]
    assert line.plc("master").scan_count > master_scans + 2000  # never restarted


def test_a_killed_master_is_seen_by_its_peers(line: Plant):
    line.faults.kill("master")
    link_cycles_until(line, lambda p: p["filler:%SW112"] == ERR_TIMEOUT, limit=MISSES + 1)
    line.scan(2)
    assert line["filler:%SW111"] == 0 and not line["filler:%M1"]  # it disables itself


def test_a_peer_in_stop_is_caught_by_its_frozen_heartbeat(line: Plant):
    line.faults.stop("filler")
    line.run(2.0)
    assert line["master:%SW111"] == 0b11  # still on the link: it answers in STOP
    assert line.run_until(lambda p: p["master:%Q0.3"], timeout=3.5)  # 3 s heartbeat timer
    line.faults.start("filler")
    assert line.run_until(lambda p: not p["master:%Q0.3"], timeout=2.0)


def test_a_broken_wire_reads_zero_until_mended(line: Plant):
    line.faults.break_wire("line enable")
    line.scan(2)
    assert not line["filler:%I0.5"] and not line["filler:%M1"]  # the station disables
    line.run(4.0)
    assert line["master:%Q0.3"]  # the master sees a station no longer enabled
    line.faults.mend_wire("line enable")
    assert line.run_until(lambda p: not p["master:%Q0.3"], timeout=1.0)
    with pytest.raises(PlantStateError, match="no wire 'nope'"):
        line.faults.break_wire("nope")


def test_a_slowed_link_delays_the_words_by_its_cycles(plant_from_file):
    def cycles_to_see_enable(delay: int) -> int:
        p = plant_from_file(PLANT)
        p.run(1.0)
        p.faults.slow_link("filler", delay)
        p["master:%I0.0"] = 1
        return link_cycles_until(p, lambda p: p["filler:%INW0.0"] == 1)

    fast, slow = cycles_to_see_enable(0), cycles_to_see_enable(3)
    assert slow - fast == 3


def test_plant_access_errors_name_what_exists(line: Plant):
    with pytest.raises(PlantStateError, match="controllers master, filler, capper"):
        line["nobody:%MW0"]
    with pytest.raises(PlantStateError, match="set by wires"):
        line["belt:run"] = 1
    assert line["belt:run"] is True
    for name in line.controllers:
        line.faults.kill(name)
    line.run(1.0)  # the belt alone goes on
    assert not line["belt:run"]


def test_a_plant_with_nothing_left_to_run_says_so(plant_from_file, tmp_path):
    (tmp_path / "p.il").write_text("LD 1\nST %Q0.0\n")
    (tmp_path / "plant.toml").write_text('[controllers.a]\nprogram = "p.il"\n')
    p = plant_from_file(tmp_path / "plant.toml")
    p.faults.kill("a")
    with pytest.raises(PlantStateError, match="nothing left to run"):
        p.scan()


@pytest.mark.plant_file("../../ladder_programs/plant/plant.toml")
def test_the_plant_fixture_loads_the_marked_file(plant: Plant):
    assert set(plant.controllers) == {"master", "filler", "capper"} and plant.time == 0


def test_plant_run_command(capsys):
    assert main(["plant", "run", str(PLANT), "--speed", "max", "--for", "10s",
                 "--set", "master:%I0.0=1", "--print", "master:%MW0", "--json"]) == 0
    out = capsys.readouterr().out
    assert '"time": 10.0' in out and '"master:%MW0": 1' in out and '"scans": 1000' in out
    # paced at 50x real time: the same plant time and result, only slower
    assert main(["plant", "run", str(PLANT), "--speed", "50", "--for", "1s",
                 "--print", "belt:run"]) == 0
    assert "t=1.000s" in capsys.readouterr().out
    assert main(["plant", "check", str(PLANT)]) == 0
    assert "3 controllers" in capsys.readouterr().out
    assert main(["plant", "run", str(PLANT), "--speed", "max", "--for", "1s",
                 "--set", "nobody:%MW0=1"]) == 1


# ---- EXCH between controllers, named in the plant file ------------------------------------------
CLIENT = """\
LD 1
[ %MW0 := 16#0106 ]
[ %MW1 := 16#0300 ]
[ %MW2 := 16#0103 ]
[ %MW3 := 0 ]
[ %MW4 := 2 ]
LD %MSG3.D
AND %M1
ANDN %MSG3.E
[ %MW20 := %MW7 ]
[ %MW21 := %MW8 ]
[ INC %MW22 ]
LD %MSG3.D
AND %M1
R %M1
LD %MSG3.D
EXCH3 %MW0:9
S %M1
"""
EXCH_PLANT = """\
[controllers.hmi]
program = "client.il"

[controllers.press]
program = "server.il"
host = "10.0.35.9"

[links.reads]
type = "exch"
client = "hmi"
remotes = { 1 = "press" }
"""


def test_an_exch_link_reads_another_controller_by_name(plant_from_file, tmp_path):
    (tmp_path / "client.il").write_text(CLIENT)
    (tmp_path / "server.il").write_text("LD 1\n[ %MW0 := 1234 ]\n[ %MW1 := 5678 ]\n")
    (tmp_path / "plant.toml").write_text(EXCH_PLANT)
    p = plant_from_file(tmp_path / "plant.toml")
    remote = p.plc("hmi").settings.exch.remote[1]  # what `plant up` would reach
    assert (remote.host, remote.port) == ("10.0.35.9", 5020)
    p.run(1.0)
    assert (p["hmi:%MW20"], p["hmi:%MW21"]) == (1234, 5678) and p["hmi:%MW22"] > 10
    p.faults.kill("press")
    p.run(0.5)
    assert p["hmi:%SW65"] == 0  # no answer yet: the exchange's 1 s timeout runs
    p.run(1.0)
    assert p["hmi:%SW65"] == ERR_EXCH_TIMEOUT  # EXCH3's status word
    done = p["hmi:%MW22"]
    p.faults.restart("press")
    p.run(2.0)
    assert p["hmi:%SW65"] == 0 and p["hmi:%MW22"] > done


def test_an_exch_link_names_controllers(tmp_path):
    (tmp_path / "client.il").write_text(CLIENT)
    (tmp_path / "server.il").write_text("LD 1\nST %Q0.0\n")
    (tmp_path / "plant.toml").write_text(EXCH_PLANT.replace('{ 1 = "press" }',
                                                            '{ 1 = "pres" }'))
    with pytest.raises(PlantError, match=r"plant.toml:11: links.reads.remotes: 'pres' is not"):
        Plant.from_file(tmp_path / "plant.toml")
    (tmp_path / "plant.toml").write_text(EXCH_PLANT.replace('client = "hmi"\n', ""))
    with pytest.raises(PlantError, match="an EXCH link names its client and its remotes"):
        Plant.from_file(tmp_path / "plant.toml")


def test_a_remote_io_controller_is_the_masters_io(plant_from_file, tmp_path):
    (tmp_path / "m.il").write_text("LD %I2.0.0\nST %Q2.0.3\nLD %I2.0.0\nST %Q0.0\n")
    (tmp_path / "plant.toml").write_text("""\
[controllers.cell]
program = "m.il"

[controllers.rio]
role = "remote_io"
address = 2

[links.line]
master = "cell"
peers = ["rio"]

[[wires]]
name = "button"
from = "cell:%Q0.1"
to = "rio:%I0.0"
""")
    p = plant_from_file(tmp_path / "plant.toml")
    assert p.plc("cell").settings.remote_link.remotes == {2: "remote_io"}
    p["cell:%Q0.1"] = 1  # drives the remote's input through the wire (published next scan)
    p.run(0.1)
    assert p["cell:%I2.0.0"] and p["cell:%Q0.0"] and p["rio:%Q0.3"]
    p.faults.kill("rio")
    p.run(0.1)
    assert not p["cell:%SW111"] and p["cell:%I2.0.0"]  # absent; the last inputs held


def test_a_remote_io_controller_has_no_program(tmp_path):
    (tmp_path / "m.il").write_text("LD 1\nST %Q0.0\n")
    (tmp_path / "plant.toml").write_text(
        '[controllers.cell]\nprogram = "m.il"\n\n[controllers.rio]\nrole = "remote_io"\n'
        'program = "m.il"\naddress = 2\n')
    with pytest.raises(PlantError, match="plant.toml:4: controllers.rio: a controller has a "
                                         "program, a remote I/O controller"):
        Plant.from_file(tmp_path / "plant.toml")
