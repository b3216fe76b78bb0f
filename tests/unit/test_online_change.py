"""Online program change (softplc.online, issue 24): check, list what is lost, swap at a
scan boundary keeping memory and blocks."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import ProgramError
from softplc.online import ChangeRefused, ProgramInfo, apply, plan

OLD = """\
LD %I0.0
IN %TM0
LD %TM0.Q
ST %Q0.0
LD %I0.1
CU %C0
LD %I0.2
CU %C1
LD 1
[ %MW5 := %MW5 + 1 ]
"""
CONFIG = {"scan_period": "10ms",
          "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 50}},
          "counters": {"%C0": {"preset": 3}}}


def running() -> PLC:
    plc = PLC.from_source(OLD, CONFIG)
    plc["%I0.0"] = 1
    plc.scan(20)  # %TM0.V = 19 (counting, preset 50)
    for _ in range(2):  # %C0.V = 2
        plc["%I0.1"] = 1
        plc.scan()
        plc["%I0.1"] = 0
        plc.scan()
    return plc


def test_a_program_change_keeps_memory_timers_and_counters():
    plc = running()
    tm, c, mw = plc["%TM0.V"], plc["%C0.V"], plc["%MW5"]
    assert (tm, c) == (23, 2)
    new = OLD.replace("ST %Q0.0", "ST %Q0.0\nST %M7")  # one more coil
    change = plan(plc, new)
    assert change.losses == [] and not change.needs_confirmation
    before = plc.program_version
    apply(plc, change)
    assert plc.program_version == before + 1
    assert (plc["%TM0.V"], plc["%C0.V"], plc["%MW5"]) == (tm, c, mw)
    plc.scan(27)  # the timer goes on from where it was: 23 + 27 = 50 -> Q
    assert plc["%TM0.Q"] == 1 and plc["%M7"] == 1 and plc["%MW5"] == mw + 27


def test_a_removed_block_is_listed_and_needs_a_confirmation():
    plc = running()
    plc["%I0.2"] = 1
    plc.scan()
    change = plan(plc, OLD.replace("LD %I0.2\nCU %C1\n", ""))
    assert change.needs_confirmation
    assert change.losses == ["%C1 is no longer used: its value is dropped"]
    with pytest.raises(ChangeRefused, match="%C1"):
        apply(plc, change)
    assert plc["%C1.V"] == 1  # refused: nothing changed
    apply(plc, change, confirm=True)
    assert 1 not in plc.mem.blocks["C"] and plc["%C0.V"] == 2


def test_a_block_still_configured_keeps_its_value_when_the_program_stops_using_it():
    plc = running()  # %C0 is configured: like a Twido's, it stays with its value
    change = plan(plc, OLD.replace("LD %I0.1\nCU %C0\n", ""))
    assert change.losses == []
    apply(plc, change)
    assert plc["%C0.V"] == 2


def test_a_changed_preset_restarts_that_block_only():
    plc = running()
    cfg = {**CONFIG, "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 80}}}
    change = plan(plc, OLD, cfg)
    assert [line for line in change.losses if "%TM0" in line]
    assert "preset 50 -> " in change.losses[0] and "preset 80" in change.losses[0]
    apply(plc, change, confirm=True)
    assert plc["%TM0.P"] == 80 and plc["%TM0.V"] == 0  # restarted from the new configuration
    assert plc["%C0.V"] == 2  # the counter carried over


def test_a_config_section_that_needs_a_restart_is_refused():
    plc = running()
    with pytest.raises(ChangeRefused, match="scan_period"):
        plan(plc, OLD, {**CONFIG, "scan_period": "20ms"})


def test_a_program_that_does_not_compile_changes_nothing():
    plc = running()
    code = plc.program
    with pytest.raises(ProgramError) as e:
        plan(plc, OLD + "LD %I0.2\nST %Q0.0\nLDD %M1\nIN %TM5\n")
    text = "\n".join(str(d) for d in e.value.diagnostics)
    assert ":13:1: unknown instruction 'LDD'" in text  # every error, with its line
    assert ":14:" in text and "%TM5" in text
    assert plc.program is code


def test_cold_change_restarts_everything():
    plc = running()
    apply(plc, plan(plc, OLD.replace("LD %I0.2\nCU %C1\n", "")), cold=True)
    assert plc["%TM0.V"] == 0 and plc["%MW5"] == 0


def test_program_info_names_the_running_code():
    plc = running()
    first = ProgramInfo.of(plc)
    apply(plc, plan(plc, OLD + "LD 1\nST %M9\n"))
    second = ProgramInfo.of(plc)
    assert first.sha256 != second.sha256 and second.version == first.version + 1
    assert set(second.as_dict()) == {"file", "sha256", "hash", "loaded_at", "version"}


def test_a_swap_that_fails_leaves_the_running_program_and_its_blocks(monkeypatch):
    """If the swap itself failed after a clean plan, blocks, settings and code stay those
    of the running program (with their values)."""
    from softplc.errors import CompileError

    plc = running()
    cfg = {**CONFIG, "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 80}}}
    change = plan(plc, OLD.replace("LD %I0.2\nCU %C1\n", ""), cfg)
    code, settings, tm = plc.program, plc.settings, plc.mem.blocks["TM"][0]

    def fail(_program):
        raise CompileError([])

    monkeypatch.setattr(plc, "replace_program", fail)
    with pytest.raises(CompileError):
        apply(plc, change, confirm=True)
    assert plc.program is code and plc.settings is settings
    assert plc.mem.blocks["TM"][0] is tm and plc["%TM0.P"] == 50 and plc["%TM0.V"] == 23
    assert plc["%C1.V"] == 0 and 1 in plc.mem.blocks["C"]
