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


# ---- %S4-%S7 from the cache of the interval they cannot change in ------------------------
# The program copies the clock bits to %M4-%M7, then writes two of them; the host writes the
# others between scans: every scan must still see the clocks at its start (re-asserted).
CLOCKS_SEEN = ("LD %S4\nST %M4\nLD %S5\nST %M5\nLD %S6\nST %M6\nLD %S7\nST %M7\n"
               "LDN %S4\nST %S4\nLD 1\nST %S6\n")


def _want(t: int) -> list[int]:
    return [1 if t % p < p // 2 else 0 for p in S_CLOCKS.values()]


def _check_scans(plc: PLC, n: int) -> None:
    for k in range(n):
        plc["%S5"] = k & 1  # a host write between scans
        plc["%S7"] = 1
        plc.scan()
        start = plc.engine.time_source.now_us
        assert [plc[f"%M{b}"] for b in S_CLOCKS] == _want(start), (start, k)


def test_clock_bits_follow_time_on_the_virtual_clock_for_any_period():
    """Periods with each cache and without (a ring for multiples of 5 ms, an interval of
    10 scans or more), bits aliased by the period (10 ms: %S4 is the same at every scan
    start) and periods longer than a half period of every clock but %S7."""
    kinds = set()
    for period_us in (100, 300, 500, 1000, 3000, 6000, 7000, 10_000, 20_000, 250_000,
                      1_000_000, 45_000_000):
        plc = PLC.from_source(CLOCKS_SEEN, {"scan_period": f"{period_us}us"})
        text = source(plc.engine)[0]
        kinds.add("ring" if "clock_ring" in text else "interval" if "nx" in text else "plain")
        _check_scans(plc, 300)
        plc.engine.clock.now_us = 59_990_000 - period_us  # %S7 falls at 60 s
        _check_scans(plc, 30)
    assert kinds == {"ring", "interval", "plain"}


def test_clock_bits_after_the_virtual_clock_is_set_between_scans():
    """A clock set forwards, backwards, or off the scan grid (a phase where the aliased %S4
    differs) without anything else: the scan notices it."""
    plc = PLC.from_source(CLOCKS_SEEN, {"scan_period": "1s"})
    text, _ = source(plc.engine)
    assert "now is not exp" in text  # the cache is in use for this period
    _check_scans(plc, 5)
    for t in (7_005_000, 3_000_000, 3_002_000, 90_000_000, 0, 30_500_000):
        plc.engine.clock.now_us = t
        _check_scans(plc, 3)


def test_clock_bits_after_restore_online_change_restarts_and_stop():
    plc = PLC.from_source(CLOCKS_SEEN, {"scan_period": "1s"})
    _check_scans(plc, 3)
    snap = plc.engine.snapshot()
    _check_scans(plc, 40)  # past a change of %S7
    plc.engine.restore(snap)
    _check_scans(plc, 3)
    plc.replace_program(PLC.from_source(CLOCKS_SEEN + "LD %S5\nST %M9\n").ast)
    _check_scans(plc, 3)
    plc.engine.cold_start()
    _check_scans(plc, 3)
    plc.engine.warm_start()
    _check_scans(plc, 3)
    plc.engine.stop()
    plc.scan(7)  # the clock runs in STOP, the bits are not asserted
    plc.engine.start()
    _check_scans(plc, 3)


def test_clock_bits_on_the_real_clock_after_it_jumps_forwards():
    plc = PLC.from_source(CLOCKS_SEEN, clock=RealClock())
    _check_scans(plc, 50)
    plc.engine.clock._t0 -= 30_002_000_000  # 30 s and 2 ms later: %S7 and %S4 change
    _check_scans(plc, 50)


def test_clock_bits_on_another_clock_that_goes_back_and_forth():
    class Jumpy(RealClock):
        virtual = True
        times = iter([0, 1000, 6000, 2000, 61_000_000, 61_004_000, 50, 4999, 5000] * 3)

        def start_scan(self, period_us: int) -> int:
            self.now_us = next(self.times)
            return self.now_us

    plc = PLC.from_source(CLOCKS_SEEN, clock=Jumpy())
    assert "now >= nx or now < lo" in source(plc.engine)[0]
    _check_scans(plc, 27)


def test_a_real_clock_scan_is_timed_from_the_clock_reading():
    """One perf_counter reading gives the real clock's time and the start of the scan's
    timing: %SW30 and the statistics still measure the scan."""
    plc = PLC.from_source("LD 1\n[ %MW0 := %MW0 + 1 ]\n", clock=RealClock())
    plc.scan(5)
    st = plc.engine.stats
    assert st.scans == 5 and 0 < st.min <= st.last <= st.max < 0.1
    assert plc["%SW30"] == plc["%SW31"] == plc["%SW32"] == 0  # each under 0.5 ms


def test_a_run_of_scans_after_a_change_generates_the_scan_once(monkeypatch):
    """`plc.scan(n)` and a caller holding `engine.scan` from before a change: the scan is
    generated once per change, not at every call (it was: the held bound method rebuilt)."""
    from softplc.runtime import engine as engine_mod

    builds: list[int] = []
    real_build = engine_mod.build

    def counting_build(eng, before=True):  # type: ignore[no-untyped-def]
        builds.append(eng.version)
        return real_build(eng, before)

    monkeypatch.setattr(engine_mod, "build", counting_build)
    plc = PLC.from_source(COPY)
    plc.scan(200)  # the first scan's bits, then the steady scan: two generations
    assert len(builds) == 2 and plc.scan_count == 200
    plc.force("%M3", 1)
    held = plc.engine.scan  # generates when first called
    for _ in range(100):
        held()
    plc.scan(100)
    assert len(builds) == 3 and plc.scan_count == 400 and plc["%M3"]
