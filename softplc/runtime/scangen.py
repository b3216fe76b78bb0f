"""The scan's start and end, generated per configuration (issue 26).

`Engine.scan()` runs a function written for what the engine holds now: no hook calls
without hooks, no device loop without devices, the virtual or real clock inlined, forced
objects handled only when something is forced, first-scan bits only on a first scan. The
engine rebuilds it when any of these changes (`Engine.invalidate`, called by its setters,
by `HookList` on a change of a hook list, and on each change of state).

The same text gives `scan_stepwise` its `begin()`/`finish(dt)` (the debugger), so the two
scans cannot drift apart. What each step does is described in `engine.py`.
"""

from __future__ import annotations

import functools
import math
import re
import time
from collections.abc import Callable, Iterable
from types import CodeType, FunctionType
from typing import TYPE_CHECKING, Any, SupportsIndex

from softplc.program import Names, Watchdog
from softplc.runtime.clock import Clock, RealClock, VirtualClock
from softplc.runtime.codecache import compile_code
from softplc.runtime.runstate import RUN, S_FALLBACK

if TYPE_CHECKING:
    from softplc.runtime.scanhost import ScanHost

# %S4-%S7: 50 % clocks [manual]; bit -> period in us
S_CLOCKS = {4: 10_000, 5: 100_000, 6: 1_000_000, 7: 60_000_000}
SW_LAST, SW_MAX, SW_MIN = 30, 31, 32


class HookList(list):
    """A list of scan hooks that tells its engine when it changes (the daemon, the web
    monitor and the debugger append to and remove from them after construction)."""

    def __init__(self, changed: Callable[[], None], items: Iterable[Any] = ()) -> None:
        super().__init__(items)
        self._changed = changed

    def _wrap(name: str) -> Any:  # noqa: N805 - a helper run in the class body
        base = getattr(list, name)

        def method(self: HookList, *args: Any) -> Any:
            result = base(self, *args)
            self._changed()
            return result
        method.__name__ = name
        return method

    for _name in ("append", "extend", "insert", "remove", "pop", "clear", "__setitem__",
                  "__delitem__", "__iadd__", "sort", "reverse"):
        locals()[_name] = _wrap(_name)
    del _name, _wrap

    def __imul__(self, n: SupportsIndex) -> HookList:
        super().__imul__(n)
        self._changed()
        return self


# Every half period is a multiple of 5 ms and they all divide 60 s: %S4-%S7 at time t are
# CLOCK_BITS[t // 5000 % 12000], one table look-up per scan instead of four modulos.
CLOCK_STEP = 5000
CYCLE_US = 60_000_000  # %S4-%S7 repeat every minute
assert all(p % (2 * CLOCK_STEP) == 0 and CYCLE_US % p == 0 for p in S_CLOCKS.values())
assert list(S_CLOCKS) == [4, 5, 6, 7]  # s[4], ..., s[7] from one tuple
# Entry k: bit i is (k * CLOCK_STEP) % p_i < p_i / 2, built a column at a time (a half period
# of 1s then of 0s, repeated), as every process pays it at import: 20x faster than per entry.
CLOCK_BITS = list(zip(*(([True] * (p // 2 // CLOCK_STEP) + [False] * (p // 2 // CLOCK_STEP))
                        * (CYCLE_US // p) for p in S_CLOCKS.values()), strict=True))


# %S4-%S7 from a cache in make()'s cells, so that most scans do no arithmetic on the
# (large) time: a new scan function, made on any change (start, online change, restore),
# starts empty. The bits are still stored every scan: a program or host write to them lasts
# until the next scan (Twido re-asserts system bits), and tracking every writer would cost
# more. Two caches (cells set up, cells declared):
CELLS = {
    # the interval [lo, nx) in which they cannot change, looked up again on leaving it
    "interval": ("lo = nx = 0; exp = -1; c4 = c5 = c6 = c7 = 0",
                 "nonlocal lo, nx, exp, c4, c5, c6, c7"),
    # the virtual clock's next scan start: a ring of the values at successive scan starts
    "ring": ("node = None; exp = -1", "nonlocal node, exp")}
HALF_PERIODS = [p // 2 for p in S_CLOCKS.values()]  # each divides the next
assert all(b % a == 0 for a, b in zip(HALF_PERIODS, HALF_PERIODS[1:], strict=False))
# The interval costs two comparisons, the cells and a look-up on leaving it, about as much
# as the plain look-up when it is left every fifth scan: used from 10 scans on
MIN_SCANS_PER_INTERVAL = 10
LOOKUP = f"clock_bits[now // {CLOCK_STEP} % {len(CLOCK_BITS)}]"


@functools.lru_cache(maxsize=4)  # 1.5 MB and 4 ms at most each (P = 5 ms)
def _ring(period_us: int, phase: int) -> list[list[Any]]:
    """Node m: [%S4, %S5, %S6, %S7 at phase + m g (mod 1 min), the node P later], where g =
    gcd(P, 1 min), a multiple of CLOCK_STEP, and 0 <= phase < g a multiple of it too: the
    scan starts of a virtual clock with period P whose time is phase (mod g)."""
    g = math.gcd(period_us, CYCLE_US)
    n = CYCLE_US // g
    nodes = [list(CLOCK_BITS[(phase + m * g) // CLOCK_STEP]) for m in range(n)]
    for m, node in enumerate(nodes):
        node.append(nodes[(m + period_us // g) % n])
    return nodes


def clock_ring(period_us: int, now: int) -> list[Any]:
    """The ring node of the scan starting at `now` (the virtual clock, period P)."""
    g = math.gcd(period_us, CYCLE_US)
    t = now % CYCLE_US
    return _ring(period_us, t % g // CLOCK_STEP * CLOCK_STEP)[t // g]


def _clock_bits_code(clock: Clock, period_us: int) -> tuple[list[str], str | None]:
    """The lines that set %S4-%S7 at the scan's start (`now`), and the cache they use.
    The virtual clock starts each scan P after the last one (`exp`, set at its end) unless
    set: a ring when it has at most 12,000 scan starts a minute (P a multiple of 5 ms),
    else an interval, where a bit whose period divides P is the same at every scan start,
    so the interval is one of the shortest other half period. A real clock only goes
    forwards: intervals of the shortest half period, one comparison. Any other clock: the
    same, both ways."""
    cell, test = HALF_PERIODS[0], "now >= nx or now < lo"
    if type(clock) is VirtualClock:
        # `is not`: the time the last scan stored, or any other value (a set clock) or
        # the same value stored by someone else (looked up again, harmless)
        if math.gcd(period_us, CYCLE_US) % CLOCK_STEP == 0:
            return ["if now is not exp:", "    node = clock_ring(P, now)",
                    "s[4], s[5], s[6], s[7], node = node"], "ring"
        cell = next((h for h in HALF_PERIODS if period_us % (2 * h)), CYCLE_US)
        test = "now >= nx or now is not exp"
        if cell < MIN_SCANS_PER_INTERVAL * period_us:
            return [f"s[4], s[5], s[6], s[7] = {LOOKUP}"], None
    elif type(clock) is RealClock:
        test = "now >= nx"
    return [f"if {test}:", f"    lo = now - now % {cell}", f"    nx = lo + {cell}",
            f"    c4, c5, c6, c7 = {LOOKUP}",
            "s[4] = c4", "s[5] = c5", "s[6] = c6", "s[7] = c7"], "interval"


def _clock_code(clock: Clock) -> tuple[str, str]:
    """(start, end) lines of the scan for this clock: the two clocks of clock.py inlined,
    any other through its methods."""
    if type(clock) is VirtualClock:  # {now}: see _make
        return "now = clock.now_us", "clock.now_us = {exp}{now} + P"
    if type(clock) is RealClock:  # t0: the program's timing starts from the same reading
        return "now = clock.now_us = ((t0 := perf_counter_ns()) - clock._t0) // 1000", ""
    return "now = clock.start_scan(P)", "clock.end_scan(P)"


def _checks_watchdog(eng: ScanHost) -> bool:
    """Does the program read the watchdog deadline (a loop: a backward jump)? Only then
    does the scan set it."""
    program = eng.program
    return program is None or eng.main is not program.main or \
        f"{Names.WATCHDOG}(" in program.source


def _forced_code(eng: ScanHost, ns: dict[str, Any], inputs: bool = False) -> list[str]:
    """Forced values re-asserted, one store per bit (`inputs`: the forced %I, after the
    latch), other objects through `Engine._apply_forced_other`."""
    prefix = "fi" if inputs else "fb"
    entries = eng._forced_inputs if inputs else eng._forced_bits
    ns.update({f"{prefix}{k}": buf for k, (buf, _, _) in enumerate(entries)})
    lines = [f"{prefix}{k}[{i}] = {v}" for k, (_, i, v) in enumerate(entries)]
    if eng._forced_other and not inputs:
        lines.append("apply_forced_other()")
    return lines


def source(eng: ScanHost, before: bool = True) -> tuple[str, dict[str, Any]]:
    """The text of `make()`, which returns (scan, begin, finish), and its namespace.
    `before=False` leaves out the before_scan hooks (a hook changed the configuration and
    the scan goes on with the new one)."""
    ns: dict[str, Any] = {
        "eng": eng, "mem": eng.mem, "s": eng.mem.s, "sw": eng.mem.sw.w, "clock": eng.clock,
        "P": eng.period_us, "DTS": eng.period_us / 1e6, "W": eng.watchdog_s, "RUN": RUN,
        "V": eng.version, "st": eng.stats, "main": eng.main, "i": eng.mem.i,
        "i_field": eng.mem.i_field,
        "q": eng.mem.q, "q_field": eng.mem.q_field, "ts": eng.time_source, "rtc": eng.rtc,
        "pulses": eng.pulses, "perf_counter": time.perf_counter,
        "perf_counter_ns": time.perf_counter_ns, "thread_time": time.thread_time,
        "Watchdog": Watchdog, "clock_bits": CLOCK_BITS, "clock_ring": clock_ring,
        "apply_forced_other": eng._apply_forced_other}
    hooks_b = [f"b{k}()" for k in range(len(eng.before_scan))] if before else []
    hooks_a = [f"a{k}()" for k in range(len(eng.after_scan))]
    ns.update({f"b{k}": h for k, h in enumerate(eng.before_scan)})
    ns.update({f"a{k}": h for k, h in enumerate(eng.after_scan)})
    start, end = _clock_code(eng.clock)
    # step 1; a hook that changed the configuration: go on with the new one ({part}: 0 for
    # scan(), 1 for begin())
    pre = hooks_b + (["if eng.version != V: return eng._resume({part})"] if hooks_b else [])
    if eng.state != RUN:  # STOP/HALT: the clock runs, hooks run, nothing else
        return _make(pre, ["clock.start_scan(P)", "clock.end_scan(P)", *hooks_a], None, [],
                     ["return False"], ns), ns
    begin = [start]  # steps 2-3
    if eng.time_source is not None:
        begin.append("ts.now_us = now")
    if eng.rtc is not None:
        begin.append("rtc.tick(now)")
    clock_bits, cells = _clock_bits_code(eng.clock, eng.period_us)
    begin += clock_bits
    begin += [f"s[{bit}] = {v}" for bit, v in eng._first.items()]
    begin += eng.mem.copy_lines("I")  # the input latch, inlined
    forced = _forced_code(eng, ns)
    begin += _forced_code(eng, ns, inputs=True) + forced
    # step 4, scan() only. On the real clock the scan's time counts from the clock's
    # reading (a perf_counter() call less; the latch and system bits are then in it)
    run = ["t0 = t0 / 1e9" if type(eng.clock) is RealClock else "t0 = perf_counter()"]
    if _checks_watchdog(eng):
        run.append("eng._deadline = t0 + W")
    if eng._suspect:  # the last scan was late: measure this one's CPU time
        run.append("eng._cpu0 = thread_time()")
    run += ["try:", "    main()", "except Watchdog:",
            "    eng._watchdog_trip(perf_counter() - t0)",
            "except Exception as e:  # any fault of the program: HALT, keep serving",
            "    eng._fault(e)", "dt = perf_counter() - t0",
            "if dt > W:", "    eng._overran(dt)"]
    if eng._suspect:
        run += ["else:", "    eng._suspect, eng._cpu0 = False, None", "    eng.invalidate()"]
    finish = []  # steps 5-7
    ts = eng.time_source
    if ts is not None and ts.track:
        finish += ["if ts.running:", "    ts.update_running()"]
    if eng.rtc is not None:
        finish.append("rtc.end_of_scan(clock.now_us)")
    if eng.pulses is not None:
        finish.append("pulses.end_of_scan(clock.now_us)")
    if eng._first:
        finish += [*(f"s[{bit}] = False" for bit in eng._first), "eng._first = {}",
                   "eng.invalidate()"]
    finish += forced
    publish = _publish_lines(eng)
    # after a HALT in this scan the output image is all 0 (Engine.halt), so publishing it
    # changes nothing, unless something writes %Q after the program: forcing, pulse
    # generators, RTC schedules
    if eng.forced or eng.pulses is not None or eng.rtc is not None:
        finish += ["if eng.state == RUN:", *(f"    {x}" for x in publish or ["pass"])]
    else:
        finish += publish
    finish += ["st.scans += 1", "st.last = dt", "st.total += dt",
               # int() of a float is the dearest step of the statistics: most scans are
               # under half a millisecond
               "if dt < 0.0005:", f"    sw[{SW_LAST}] = ms = 0", "else:",
               "    ms = int(dt * 1000 + 0.5)",
               f"    sw[{SW_LAST}] = ms = ms if ms < 32767 else 32767",
               "if dt > st.max:", "    st.max = dt", f"    sw[{SW_MAX}] = ms",
               # the first scan's time is the minimum (regenerated after it: _first)
               "if dt < st.min" + (" or st.scans == 1:" if eng.stats.scans == 0 else ":"),
               "    st.min = dt", f"    sw[{SW_MIN}] = ms"]
    if end:  # {exp}: the virtual clock's next start, for the %S4-%S7 cache
        finish.append(end.replace("{exp}", "exp = " if cells else ""))
    if eng.devices:
        ns.update({f"d{k}": d.update for k, d in enumerate(eng.devices.values())})
        finish += ["t = clock.now_us / 1e6",
                   *(f"d{k}(t, DTS)" for k in range(len(eng.devices)))]
    finish += hooks_a
    return _make(pre, begin, run, finish, ["return True"], ns, cells), ns


def _publish_lines(eng: Any) -> list[str]:
    """The output publication (%Q image -> physical outputs) as lines of Python: with %S9
    set, the outputs at their fallback value 0 instead (Engine.stop's rule, in RUN)."""
    copy = eng.mem.copy_lines("Q")
    if not copy:
        return []
    fallback = [line.split(" = ")[0] + " = False" for line in copy]
    return [f"if s[{S_FALLBACK}]:", *(f"    {x}" for x in fallback), "else:",
            *(f"    {x}" for x in copy)]


_NAME = re.compile(r"(?<![.\w])[A-Za-z_]\w*")  # a name, not an attribute


def _make(pre: list[str], begin: list[str], run: list[str] | None, finish: list[str],
          begun: list[str], ns: dict[str, Any], cells: str | None = None) -> str:
    """make() -> (scan, begin, finish). `run` None: STOP or HALT, the scan is `pre` +
    `begin` and `finish` does nothing. The names of `ns` each function reads are its
    default arguments: LOAD_FAST rather than LOAD_GLOBAL, about 20 ns a scan."""
    def fn(name: str, params: list[str], lines: list[str], part: int) -> str:
        # {now}: the scan's start time, a local of scan() (nothing moves the clock in a
        # scan) but not of finish()
        now = "clock.now_us" if name == "finish" else "now"
        text = "".join(f"        {x}\n".replace("{part}", str(part)).replace("{now}", now)
                       for x in lines) or "        pass\n"
        params = params + [f"{n}={n}" for n in sorted(set(_NAME.findall(text)) & ns.keys())]
        # every function of a make() with cells declares them, used or not: handover()
        # replaces their code, which needs the same number of free variables
        text = f"        {CELLS[cells][1]}\n{text}" if cells else text
        return f"    def {name}({', '.join(params)}):\n{text}"

    scan = [*pre, *begin,
            *(run + finish if run is not None else [])]
    return ("def make():\n" + (f"    {CELLS[cells][0]}\n" if cells else "")
            + fn("scan", [], scan, 0) + fn("begin", [], pre + begin + begun, 1)
            + fn("finish", ["dt"], finish, 0) + "    return scan, begin, finish\n")


# What `Engine.invalidate` puts into a generated scan a caller may still hold (PLC.scan(n),
# benchmarks): it hands over to the current one, so the scan itself checks nothing. One
# code per number of free variables (with or without the clock-bit cells).
_HANDOVER_TEXT = "def scan():\n    return eng.scan()\n"
_HANDOVERS = {len(c.co_freevars): c for c in (
    compile(_HANDOVER_TEXT, "<scan handover>", "exec").co_consts[0],
    *(next(c for c in compile(
        f"def make():\n    {setup}\n    def scan():\n        {declared}\n"
        "        return eng.scan()\n", "<scan handover>", "exec").co_consts[0].co_consts
        if isinstance(c, CodeType)) for setup, declared in CELLS.values()))}
assert len(_HANDOVERS) == 1 + len(CELLS)


def handover(fn: FunctionType) -> None:
    """Make a generated function `fn` hand over to the engine's current scan."""
    fn.__code__ = _HANDOVERS[len(fn.__code__.co_freevars)]


# What `Engine.invalidate` puts in `engine.scan`: generates the scan when called. A
# function rather than a bound method, so that `Engine._rebuild` can hand it over too: a
# caller holding it (`PLC.scan(n)`, a benchmark's loop) would otherwise generate again at
# every call (650 us a scan).
REBUILD = compile("def scan():\n    return eng._rebuild()\n", "<scan rebuild>", "exec"
                  ).co_consts[0]


def rebuilder(eng: ScanHost) -> Callable[[], None]:
    return FunctionType(REBUILD, {"eng": eng})


def build(eng: ScanHost, before: bool = True) -> tuple[Callable[[], None],
                                                     Callable[[], bool],
                                                     Callable[[float], None]]:
    """(scan, begin, finish) for the engine as it is now."""
    text, ns = source(eng, before)
    exec(compile_code(text, "<scan>"), ns)
    return ns["make"]()
