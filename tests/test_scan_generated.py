"""The scan generated per configuration (runtime/scangen.py, issue 26): it follows every
change of hooks, devices, forcing, run state and I/O in use, and computes what the generic
scan did (clocks %S4-%S7 included)."""

from __future__ import annotations

from softplc import PLC
from softplc.runtime.clock import RealClock
from softplc.runtime.scangen import CLOCK_BITS, CLOCK_STEP, S_CLOCKS, source

COPY = "LD %I0.0\nST %Q0.0\n"


def test_hooks_added_and_removed_after_scans_take_effect():
    plc = PLC.from_source(COPY)
    plc.scan(3)
    calls: list[str] = []
    before, after = (lambda: calls.append("b")), (lambda: calls.append("a"))
    plc.before_scan.append(before)
    plc.after_scan.insert(0, after)
    plc.scan(2)
    assert calls == ["b", "a", "b", "a"]
    plc.before_scan.remove(before)
    del plc.after_scan[0]
    plc.scan(2)
    assert calls == ["b", "a", "b", "a"]


def test_a_scan_held_before_a_change_runs_the_new_configuration():
    """`scan = plc.engine.scan` taken earlier (PLC.scan(n), benchmarks) is not stale."""
    plc = PLC.from_source(COPY)
    held = plc.engine.scan
    held()
    seen: list[int] = []
    plc.after_scan.append(lambda: seen.append(plc.scan_count))
    held()
    held()
    assert seen == [2, 3]


def test_a_before_hook_that_stops_the_plc_stops_this_scan():
    plc = PLC.from_source("LD 1\n[ INC %MW0 ]\n")
    plc.scan(2)
    plc.before_scan.append(plc.engine.stop)
    plc.scan()
    assert plc["%MW0"] == 2 and plc.engine.state == "STOP"
    t = plc.time
    plc.scan()
    assert plc.time > t  # in STOP the clock runs on


def test_an_io_address_named_after_scans_is_latched_and_published():
    """An API write to a channel the program does not name widens the copies (use_io):
    the generated scan inlines them, so it is regenerated."""
    plc = PLC.from_source(COPY)
    plc.scan(2)
    plc["%I0.7"] = 1
    plc.scan()
    assert plc["%I0.7"] == 1
    plc["%Q0.9"] = 1
    plc.scan()
    assert plc.mem.q_field[9] == 1


def test_devices_and_forcing_set_after_scans():
    plc = PLC.from_source(COPY)
    plc.scan()
    times: list[float] = []

    class Dev:
        def update(self, t: float, dt: float) -> None:
            times.append(t)

    plc.engine.devices = {"d": Dev()}
    plc.scan(2)
    assert times == [0.02, 0.03]  # after the clock's step, as before
    plc.force("%Q0.0", 1)
    plc.scan()
    assert plc.mem.q_field[0] == 1
    plc.unforce("%Q0.0")
    plc.scan()
    assert plc.mem.q_field[0] == 0


def test_clock_bits_table_matches_the_definition():
    for t in [*range(0, 200_000, 2_500), 29_999_999, 30_000_000, 59_999_999, 60_000_000,
              123_456_789, 7 * 60_000_000 + 30_004_999]:
        want = tuple(1 if t % p < p // 2 else 0 for p in S_CLOCKS.values())
        assert CLOCK_BITS[t // CLOCK_STEP % len(CLOCK_BITS)] == want, t


def test_clock_bits_on_the_real_clock_follow_time():
    plc = PLC.from_source(COPY, clock=RealClock())
    plc.engine.clock._t0 -= 3_250_000_000  # 3.25 s ago: %S6 (1 s) low, %S7 (1 min) high
    plc.scan()
    now = plc.engine.clock.now_us
    assert [plc.mem.s[b] for b in S_CLOCKS] == [
        1 if now % p < p // 2 else 0 for p in S_CLOCKS.values()]


def test_nothing_configured_means_no_hook_device_or_forcing_code():
    plc = PLC.from_source(COPY)
    plc.scan()
    text, _ = source(plc.engine)
    assert "b0()" not in text and "a0()" not in text and "d0(" not in text
    assert "forced" not in text and "clock.now_us = exp = now + P" in text


def test_a_loop_loaded_later_still_trips_the_watchdog():
    """A program without a backward jump never reads the deadline, so the scan does not
    set it; a looping program loaded in its place must get it back."""
    plc = PLC.from_source(COPY, {"watchdog": "10ms"})
    plc.scan(2)
    assert "_deadline" not in source(plc.engine)[0]
    plc.replace_program(PLC.from_source("LD 1\nST %Q0.0\n%L1:\nLD %M0\nJMPC %L1\n").ast)
    plc.scan()
    assert plc.state == "RUN" and plc.mem.q_field[0] == 1
    plc["%M0"] = 1
    plc.scan()
    assert plc.state == "HALT" and plc["%S11"]


LOOP = "LD 1\nST %Q0.0\n%L1:\nLD %M0\nJMPC %L1\n"  # loops while %M0


def test_a_halt_in_the_scan_leaves_the_field_outputs_at_zero():
    """Without forcing, pulses or RTC the scan publishes without looking at the state:
    HALT has zeroed the output image, so the field gets zeros."""
    plc = PLC.from_source(LOOP, {"watchdog": "10ms"})
    plc.scan()
    assert plc.mem.q_field[0] == 1
    plc["%M0"] = 1
    plc.scan()
    assert plc.state == "HALT" and "watchdog" in plc.engine.fault
    assert plc.mem.q_field[0] == 0


def test_a_forced_output_is_not_published_in_halt():
    plc = PLC.from_source(LOOP, {"watchdog": "10ms"})
    plc.force("%Q0.3", 1)
    plc.scan()
    assert plc.mem.q_field[3] == 1
    plc["%M0"] = 1
    plc.scan()
    assert plc.state == "HALT" and plc.mem.q_field[3] == 0


def test_hooks_changed_from_another_thread_while_scanning():
    """The web monitor and the daemon add and remove hooks from their own threads: every
    scan runs with some consistent configuration and the last change wins."""
    import threading

    plc = PLC.from_source(COPY)
    done = threading.Event()

    def churn() -> None:
        for _ in range(300):
            def h() -> None:  # a new hook object each time
                pass
            plc.after_scan.append(h)
            plc.after_scan.remove(h)
        done.set()

    t = threading.Thread(target=churn)
    t.start()
    n = 0
    while not done.is_set() and n < 200_000:
        plc.scan()
        n += 1
    t.join(10)
    assert not t.is_alive() and plc.state == "RUN" and plc.scan_count == n
    seen: list[int] = []
    plc.after_scan.append(lambda: seen.append(1))
    plc.scan(2)
    assert seen == [1, 1] and len(plc.after_scan) == 1
