"""The debugger over a whole plant (softplc.debug.plant_session) on the example line
(ladder_programs/plant): every controller stepped on the plant's clock, breakpoints in
any controller stop the plant inside that scan, `back` rewinds every controller, the belt
and the Remote Link."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.debug.plant_session import PlantSession

PLANT = Path(__file__).resolve().parents[2] / "ladder_programs" / "plant" / "plant.toml"
TOOL_RUNG = 3  # station.il: "the tool works while the time runs" (writes %Q0.0)


@pytest.fixture
def s(plant_from_file) -> PlantSession:
    """A session on the example plant, the line switched on (queued for the first scan)."""
    session = PlantSession(plant_from_file(PLANT))
    assert "queued" in session.execute("set master:%I0.0 1")
    yield session
    session.close()


def test_a_breakpoint_in_a_peer_stops_the_whole_plant_at_that_scan(s: PlantSession) -> None:
    p = s.plant
    assert s.execute("break when filler:%Q0.0 rises").startswith("breakpoint #1 when %Q0.0")
    out = s.execute("continue")
    assert out.startswith("[filler] breakpoint #1 when %Q0.0 rises (in rung 3")
    filler, master, capper = (p.controllers[n].plc for n in ("filler", "master", "capper"))
    # stopped inside the filler's scan of this instant, the focus moved to it
    assert s.focus == "filler" and s.sessions["filler"].ctl.in_scan
    assert s.execute("print %Q0.0").startswith("%Q0.0 TOOL = 1")  # the filler's own
    assert p["belt:at_fill"] and p["filler:%I0.0"]  # the box is at the filler
    # the master (before it in the file) has scanned at this instant, the capper not yet
    now = p.now_us
    assert master.clock.now_us > now and capper.clock.now_us <= now
    assert "still to scan at this instant: capper" in out
    capper_scans, belt = capper.scan_count, p.devices["belt"].state()
    assert s.execute("print capper:%MW0") == "%MW0 = 0"
    # finishing the instant runs the capper's scan; the belt waits for the next instant
    s.execute("scan 0")
    assert not s.due and capper.scan_count == capper_scans + 1
    assert p.devices["belt"].state() == belt and p.now_us == now
    assert filler.scan_count == master.scan_count  # one scan period: one scan each


def test_a_rung_breakpoint_in_a_peer_then_stepping_its_rungs(s: PlantSession) -> None:
    p = s.plant
    assert s.execute(f"break capper:{TOOL_RUNG}").startswith(f"breakpoint #1 at rung {TOOL_RUNG}")
    out = s.execute("continue")
    assert out.startswith(f"[capper] breakpoint #1 at rung {TOOL_RUNG}")
    assert s.sessions["capper"].pos == (TOOL_RUNG, 0)
    master, filler = p.controllers["master"].plc, p.controllers["filler"].plc
    assert (master.scan_count, filler.scan_count) == (1, 1)  # both scanned this instant
    assert s.execute("step").startswith(f"[scan 0, t = 0.000 s] before rung {TOOL_RUNG + 1}")
    s.execute("delete")
    assert "no breakpoints" in s.execute("breakpoints")
    s.execute("scan 3")  # finishes this instant, then 3 more scans of the capper
    assert p.controllers["capper"].plc.scan_count == 4 and master.scan_count == 4


def test_back_restores_every_controller_the_belt_and_the_link(s: PlantSession) -> None:
    p = s.plant
    s.execute("break when filler:%Q0.0 rises")
    s.execute("continue")
    s.execute("scan 0")  # to the plant's boundary
    s.execute("delete")
    before, instants = p.snapshot(), s.instants
    link = p.links["line"]
    cycles = link.cycles
    out = s.execute("run 3s")  # a box filled, capped, another fed
    assert out.startswith("[plant t = ")
    after = p.snapshot()
    assert after["devices"] != before["devices"] and link.cycles > cycles
    assert p["filler:%MW0"] >= 1
    assert s.execute(f"back {s.instants - instants}").startswith(
        f"[plant t = {before['time'] / 1e6:.3f} s")
    assert p.snapshot() == before and link.cycles == cycles
    # the same three seconds again: the same plant (the link's stations and lines too)
    s.execute("run 3s")
    assert p.snapshot() == after


def test_back_from_inside_a_scan_restores_the_instant(s: PlantSession) -> None:
    s.execute("run 1s")
    before = s.plant.snapshot()
    s.execute("break filler:0")
    s.execute("continue")
    assert s.sessions["filler"].ctl.in_scan
    s.execute("back 1")  # the instant in progress counts as one
    assert not s.due and not s.sessions["filler"].ctl.in_scan
    assert s.plant.snapshot() == before


def test_ctl_focuses_a_controller_and_qualified_objects(s: PlantSession) -> None:
    s.execute("run 5s")
    assert s.focus == "master"
    assert s.execute("print %MW0") == s.execute("print master:%MW0")
    counted = s.execute("print filler:%MW0")
    assert "no controller" in s.execute("ctl nobody")
    # 10 ms instants from 0 up to 5 s: the 501st at 5.000 s
    assert s.execute("ctl filler").startswith("[plant t = 5.000 s, instant 501] filler:")
    assert s.execute("print %MW0") == counted and int(counted.split("=")[1]) >= 1
    assert "* filler" in s.execute("ctl")
    assert s.execute("print belt:at_fill") in ("belt:at_fill = 0", "belt:at_fill = 1")
    assert "shared device" in s.execute("set belt:run 1")
    assert "one controller per command" in s.execute("print filler:%MW0 capper:%MW0")
    assert "reload is not available" in s.execute("reload")


def test_link_shows_every_station_words(s: PlantSession) -> None:
    s.execute("run 1s")
    out = s.execute("link")
    assert out.splitlines()[0].startswith("master: address 0 (master)   %SW111=16#0003")
    assert "filler: address 1 (peer)   %SW111=16#0001" in out
    assert "capper: address 2 (peer)   %SW111=16#0002" in out
    assert s.execute("link capper").startswith("capper: address 2")
    # the master's %QNW1.1 (the filler's work time) arrives as the filler's %INW0.1
    sent = s.execute("print master:%QNW1.1").split("=")[1].split()[0]
    assert s.execute("print filler:%INW0.1").split("=")[1].split()[0] == sent != "0"


def test_errors_are_text_and_commands_are_listed(s: PlantSession) -> None:
    assert s.execute("continue").startswith("error: no breakpoint is enabled")
    assert s.execute("back 2").startswith("error: only 0 instants of history")
    assert s.execute("scan x").startswith("error: 'x' is not a count")
    assert s.execute("run").startswith("error: run N")
    assert s.execute("run 1parsec").startswith("error:")
    text = s.execute("help")
    assert "ctl [NAME]" in text and "back [N]: the whole plant" in text and "watch" in text
    assert s.execute("quit") == "" and s.done


def test_an_interrupt_stops_the_plant_at_the_next_instant(s: PlantSession) -> None:
    s.sessions["capper"].plc.after_scan.append(s.interrupt)  # Ctrl-C during the 1st instant
    out = s.execute("run 10s")
    assert out.startswith("[master] interrupted") and s.instants == 1
    assert not s.due  # the instant was finished first: every controller scanned once
    assert all(c.plc.scan_count == 1 for c in s.plant.controllers.values())
