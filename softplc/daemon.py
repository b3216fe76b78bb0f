"""`softplc run`: the scan engine on a periodic clock plus a Modbus TCP server.

Threads: the main thread runs the scan loop (precise absolute-deadline sleeps, signal
handling, statistics); the Modbus server runs its asyncio loop in a background thread
(`ServerThread`); a third thread flushes the retained state to disk every save interval
so an msync never delays a scan. Modbus traffic meets the scan only through `ModbusImage`:
writes wait in its pending image and are applied by a `before_scan` hook, reads come from
the snapshot an `after_scan` hook takes, which also commits the retained image to the
memory-mapped state file (`runtime.retain.StateStore`).

Start-up order: bind the port, lock and read the state file, then open anything for
writing (`open_outputs`, e.g. the trace CSV). Stop (SIGINT/SIGTERM): the scan in progress
finishes, or is cut short at once if it loops (its memory is then neither shown nor
kept: the state is the last scan boundary's); further signals are ignored.

Periodic mode [manual]: a scan starts every %SW0 ms; a scan longer than the period sets
%S19 (through `plc.engine.note_overrun()`) and the next scan starts at once. A program that
writes another value to %SW0 changes the period (2..150 ms on a Twido; 1..10000 here).
On a shared host a scan may also start late (the OS ran something else): a cycle that
ends past its period because its start was late is an overrun too, as the program sees
it (%S19), and the scheduled starts that passed meanwhile are skipped, never made up by
back-to-back scans: the schedule restarts from the end of the late cycle (`_next_start`).

`speed` runs the virtual clock: each scan advances PLC time by the period but starts
every period/speed seconds of real time (`math.inf`: back to back), for simulations.
With a virtual clock and `host_wait` (config `[daemon] host_wait = "%Mi"`, a bit the
program sets while it waits for its host), the daemon holds the clock while that bit is 1
and no host write is pending: it runs no scan until a host writes. A write reaches the
PLC at the same PLC time however long the host took, so runs are repeatable (identical
traces); real time (no `speed`) ignores the bit. An EXCH exchange in progress holds the
virtual clock the same way, in 0.1 s slices, until its outcome or its deadline
(`runtime/exch.py`).
"""

from __future__ import annotations

import errno
import gc
import logging
import math
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from softplc import assembly as build
from softplc import online
from softplc.errors import SoftPLCError
from softplc.modbus import ModbusImage, ReadOnly, ServerThread
from softplc.modbus.regmap import describe
from softplc.modbus.server import DEFAULT_IDLE_TIMEOUT, bind_listeners
from softplc.modbus.tags import host_read_only
from softplc.persist import retain
from softplc.persist.keeper import StateKeeper
from softplc.persist.kept import ProgramKeeper
from softplc.runtime.engine import HALT, RUN

log = logging.getLogger("softplc.daemon")

MIN_PERIOD_MS, MAX_PERIOD_MS = 1, 10000
SWITCH_INTERVAL = 0.0002  # seconds; see Daemon.run


@dataclass
class DaemonOptions:
    host: str = "127.0.0.1"  # "localhost": both 127.0.0.1 and ::1
    port: int = 5020
    period: float = 0.010  # seconds, a whole number of ms
    state: Path | None = None
    state_symlink: bool = False  # a --state that is a symbolic link is used (else refused)
    cold: bool = False
    keep_state: bool = False  # warm restart even if the program or configuration changed
    # run the program kept beside the state file (softplc.persist.kept) whatever the
    # command line's program is
    program_from_state: bool = False
    save_interval: float = 5.0  # seconds between flushes to disk; 0 = only at shutdown
    speed: float | None = None  # None: real time; N: N x real time; math.inf: max
    # seconds; 0 = none (SIGUSR1 still prints one). A line every minute, not every few
    # seconds: the banner (the monitor's URL) stays on a terminal's screen
    stats_interval: float = 60.0
    max_clients: int = 32
    frame_timeout: float = 2.0
    idle_timeout: float | None = DEFAULT_IDLE_TIMEOUT  # None: never
    rt_priority: int = 10  # SCHED_FIFO priority of the scan thread; 0 = normal scheduling
    # %M index of the program's "waiting for the host" bit: with a virtual clock (speed
    # set) no scan runs, so no PLC time passes, while it is 1 and no write is pending
    host_wait: int | None = None
    # called each time the clock starts waiting for the host (e.g. flush the trace file:
    # it is written every simulated second, and simulated time now stands still)
    on_host_wait: list[Callable[[], None]] = field(default_factory=list)
    read_only: bool = False  # every host write refused (exception 01)
    allow: tuple[Any, ...] | None = None  # client networks (ipaddress); None = any
    # Opened once the port is bound and the state file locked (e.g. the trace CSV): a
    # start that fails never touches another daemon's files.
    open_outputs: list[Callable[[], None]] = field(default_factory=list)
    # Called once the Modbus server runs, with it and the image: other front-ends (a web
    # monitor) start on `server.loop` and write through `image.write_words/write_bits`.
    on_serving: list[Callable[[ServerThread, ModbusImage], None]] = field(
        default_factory=list)
    web: Any = None  # softplc.web.WebOptions; None = no web monitor
    # the folder an online change's configuration may name files in (--config-dir);
    # None: only the files the request carries (softplc.config.files)
    config_dir: Path | None = None
    gc_freeze: bool = True  # freeze what start-up made (see Daemon.run); False: comparisons
    # the Remote Link over TCP (softplc.runtime.linktcp: a MasterService or RemoteService,
    # already bound): it meets the scans at their boundaries, runs in threads of its own
    link: Any = None
    # the wired inputs and outputs over TCP (softplc.access.wires.WireService, already
    # bound): its input changes go through the access port's queue, as the web monitor's
    wires: Any = None


def percentiles(samples: list[float], *ps: float) -> list[float]:
    """Nearest-rank percentiles (0 for no samples)."""
    if not samples:
        return [0.0 for _ in ps]
    s = sorted(samples)
    return [s[min(len(s) - 1, max(0, math.ceil(p / 100 * len(s)) - 1))] for p in ps]


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:.3f}ms"


class Daemon:
    """Runs a PLC periodically with a Modbus server until `request_stop` (or a signal)."""

    def __init__(self, plc: Any, options: DaemonOptions, *, program_name: str = "",
                 app: bytes = b"", out: TextIO | None = None):
        self.plc = plc
        self.opt = options
        self.program_name = program_name
        self.app = app  # retain.application_id of the program and configuration
        self.out = out or sys.stdout
        self._stop = False
        self._scanning = False
        self.interrupted = False  # a scan was cut short by a stop request
        self.signals = 0
        self.stats_wanted = False  # SIGUSR1: a statistics line at the next scan
        self.image: ModbusImage | None = None
        self.keeper: ProgramKeeper | None = None  # the program kept with the state file
        self._server: ServerThread | None = None
        self.overruns = 0  # cycles that missed their period (each one sets %S19)
        self.late_starts = 0  # of which the scan itself was short: its start was late
        self.skipped_starts = 0  # scheduled starts that passed during those cycles
        self.clock: Callable[[], float] = time.perf_counter  # the loop's time (tests: a fake)
        self.sleep: Callable[[float], None] = time.sleep
        self.jitter: list[float] = []  # scan start lateness, current stats window
        self.jitter_max = 0.0
        self.start_mode = ""
        self.start_why = ""
        self.priority = ""
        self.web: Any = None  # the web monitor (softplc.web), if any
        ms = options.period * 1000
        if abs(ms - round(ms)) > 1e-9 or not MIN_PERIOD_MS <= round(ms) <= MAX_PERIOD_MS:
            raise SoftPLCError(f"period {ms:g} ms: must be a whole number of ms from "
                               f"{MIN_PERIOD_MS} to {MAX_PERIOD_MS}")
        self.period_ms = round(ms)

    def request_stop(self, *_: Any) -> None:
        """Stop after the current scan, or at once if the scan loops (signal handler, other
        threads). The state kept is the last scan boundary's; a repeated request is
        ignored (a second Ctrl-C never cuts the shutdown short)."""
        if self._stop:
            return
        self._stop = True
        if self.image is not None:
            self.image.written.set()  # wakes a loop waiting for the host
        if self._scanning:
            self.interrupted = True
            if self.image is not None:
                self.image.hold = True  # the cut-short scan's memory is neither shown nor kept
            self.plc.engine.interrupt()

    def _on_signal(self, *_: Any) -> None:
        self.signals += 1
        self.request_stop()

    def _on_stats(self, *_: Any) -> None:
        self.stats_wanted = True

    def say(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    # -- set-up --------------------------------------------------------------------------
    def _set_period(self, ms: int) -> None:
        self.period_ms = ms
        self.period = ms / 1000
        self.interval = 0.0 if self.opt.speed == math.inf else self.period / (self.opt.speed or 1)
        self.plc.set_scan_period(self.period)

    def _banner(self, server: ServerThread, image: ModbusImage) -> None:
        plc, opt = self.plc, self.opt
        rungs = len(plc.program.rungs)
        clock = "real time" if opt.speed is None else (
            "virtual clock, as fast as possible" if opt.speed == math.inf
            else f"virtual clock x{opt.speed:g}")
        self.say(f"softplc run: {self.program_name} ({rungs} rungs), period {self.period_ms} ms "
                 f"({clock}), {self.start_mode} start ({self.start_why}), state {plc.state}")
        if opt.state is not None:
            every = f"every {opt.save_interval:g} s and " if opt.save_interval else ""
            self.say(f"retained state: {opt.state} (locked; every scan and every write kept "
                     f"through a process kill; flushed to disk {every}at shutdown)")
        self.say(f"scan thread: {self.priority}")
        if plc.devices:
            self.say("simulated devices: " + ", ".join(plc.devices))
        for line in describe(image.n_registers, image.n_coils, image.read_only):
            self.say("  " + line)
        if opt.read_only:
            self.say("  read-only: every write is answered with exception 01")
        if opt.allow is not None:
            self.say("  clients allowed from: " + ", ".join(str(n) for n in opt.allow))
        for service in (opt.link, opt.wires):
            if service is not None:
                self.say(service.banner())
        for line in self.web.banner() if self.web is not None else ():  # web monitor hook
            self.say(line)
        # The last banner line: tools and tests wait for it.
        self.say("Modbus TCP server listening on " + ", ".join(server.server.addresses))

    def _bind(self) -> list[Any]:
        opt = self.opt
        try:
            return bind_listeners(opt.host, opt.port)
        except OSError as e:
            raise SoftPLCError(
                f"cannot listen on {opt.host}:{opt.port}: {e.strerror or e}"
                + ("; is another softplc running? choose another --port (or PORT=... make "
                   "run)" if e.errno == errno.EADDRINUSE else "")) from None

    def _open_state(self) -> retain.StateStore | None:
        """Lock and read the state file, then cold or warm start (sets start_mode/why)."""
        plc, opt = self.plc, self.opt
        if opt.state is None:
            plc.cold_start()
            self.start_mode, self.start_why = "cold", "no --state file"
            return None
        store = retain.StateStore.open(opt.state, follow_symlinks=opt.state_symlink)
        try:
            state = None
            try:
                state = store.load()
            except retain.StateFileError:
                if not opt.cold:
                    raise
            why = self._choose_program(state)
            self.start_mode, self.start_why = retain.restart(
                plc, state, cold=opt.cold, keep_state=opt.keep_state, app=self.app,
                where=f"state file {opt.state}")
            if self.start_mode == "warm":
                self.start_why = why
            store.start(retain.capture(plc.mem, self.app))
            store.set_pid()
        except BaseException:
            store.close()
            raise
        return store

    def _choose_program(self, state: retain.RetainedState | None) -> str:
        """Which program runs (`online.choose_program`: the command line's, or the one
        kept with the state file's data); keep it beside the state file. Why, for the
        banner."""
        plc, opt = self.plc, self.opt
        assert opt.state is not None
        keeper = self.keeper = ProgramKeeper(opt.state)
        why, command_line = "", self.app
        if state is not None and not opt.cold:
            retain.check_compatible(state, plc.mem, f"state file {opt.state}")
            self.app, why = online.choose_program(
                plc, state.app, self.app, keeper, keep_state=opt.keep_state,
                from_state=opt.program_from_state, state=opt.state)
        kept = keeper.find(self.app) if self.app != command_line else None
        if kept is not None:
            self.program_name = f"{kept.file} (kept with the state)"
        else:
            kept = online.kept_record(plc, self.app, self.app, file=self.program_name)
        keeper.keep(kept)
        keeper.running = kept
        return why

    # -- the loop ------------------------------------------------------------------------
    def run(self) -> int:
        plc, opt = self.plc, self.opt
        # Order matters: nothing is opened for writing until the port is ours and the
        # state file locked, so a second daemon that cannot start harms nothing.
        sockets = self._bind()
        try:
            store = self._open_state()
        except BaseException:
            for s in sockets:
                s.close()
            raise
        try:
            for open_output in opt.open_outputs:
                open_output()
            self._set_period(self.period_ms)
            blocks = None
            if store is not None:
                def blocks() -> bytes:
                    return retain.encode_blocks(retain.capture_blocks(plc.mem))
            ro, device_words = host_read_only(plc)
            # devices' status words (e.g. a servo axis's) are read-only for hosts too
            device_ro = tuple(r for ranges in device_words.values() for r in ranges)
            image = self.image = ModbusImage(
                plc.mem, ReadOnly(ro.registers + device_ro, ro.coils), store=store,
                blocks=blocks, writes_allowed=not opt.read_only)
            for dev in plc.devices.values():  # a value a device refuses: exception 03
                if dev.word_check is not None:
                    image.check_values(dev.word_check.ranges(), dev.word_check.refusal)
            plc.before_scan.append(image.apply_writes)
            plc.after_scan.append(image.take_snapshot)
            server = ServerThread(image, opt.host, opt.port, sockets=sockets,
                                  max_clients=opt.max_clients, frame_timeout=opt.frame_timeout,
                                  idle_timeout=opt.idle_timeout, allow=opt.allow)
            server.start()
            self._server = server
            if opt.link is not None:
                opt.link.attach(plc)
                if opt.speed != math.inf:  # the Modbus thread's priority (see _realtime)
                    opt.link.priority = max(0, opt.rt_priority - 1)
                opt.link.start()
            web = opt.web is not None and opt.web.port is not None
            access = None
            if web or opt.wires is not None:  # one access port, one command queue
                from softplc.access import AccessPort

                access = AccessPort(plc, image)
                access.program.files_root = opt.config_dir
                access.program.keeper = self.keeper  # an online change is kept with the state
            if opt.wires is not None:
                opt.wires.attach_access(plc, access)
                opt.wires.start()
            # web monitor hook: served on the Modbus server's event loop (softplc.web)
            if web:
                from softplc.web import attach

                self.web = attach(self, server, access, opt.web)
            for hook in opt.on_serving:
                hook(server, image)
        except BaseException:
            if self.web is not None:
                self.web.stop()
            if self._server is not None:
                self._server.stop()
            for service in (opt.link, opt.wires):
                if service is not None:
                    service.stop()
            for s in sockets:
                s.close()
            if store is not None:
                store.close()
            raise
        keeper = None
        if store is not None:
            keeper = StateKeeper(store, opt.save_interval, self._state_kept, self.say)
        # Until the very end a signal only sets flags: a second Ctrl-C cannot interrupt
        # the shutdown half-way or change the exit status.
        old_handlers = {s: signal.signal(s, self._on_signal)
                        for s in (signal.SIGINT, signal.SIGTERM)}
        if hasattr(signal, "SIGUSR1"):  # `kill -USR1 PID`: statistics on request
            old_handlers[signal.SIGUSR1] = signal.signal(signal.SIGUSR1, self._on_stats)
        # The scan thread and the Modbus thread share the GIL. A thread that wants it waits
        # up to the switch interval (5 ms by default) for a busy holder to let go: that
        # would be scan-start jitter under Modbus load (and Modbus latency during
        # back-to-back scans at --speed max). 0.2 ms keeps both well under 1 ms.
        old_switch = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL)
        try:
            try:
                self.priority = self._realtime()  # after the other threads started
                self._banner(server, image)
                if opt.gc_freeze:
                    # The program, its compiled code, the image and the servers live as long
                    # as the daemon: moved out of the collector's generations, a full
                    # collection (triggered by any thread's allocations, holding the GIL)
                    # no longer walks them, so it stops delaying scan starts.
                    gc.collect()
                    gc.freeze()
                self._loop(server)
            finally:
                sys.setswitchinterval(old_switch)
                if opt.gc_freeze:
                    gc.unfreeze()  # collectable again (a daemon run inside a longer process)
                self._shutdown(server, store, keeper)
        finally:
            # Stopped by a signal: the process is on its way out and more signals (Ctrl-C
            # held down) must not change its exit status: ignore them from now on.
            for s, h in old_handlers.items():
                signal.signal(s, signal.SIG_IGN if self.signals else h)
        return 0

    def _realtime(self) -> str:
        """Put the calling (scan) thread in SCHED_FIFO, if allowed. Threads started before
        keep their normal priority. Without it, a busy machine delays wake-ups by
        several ms (CFS scheduling latency)."""
        prio = self.opt.rt_priority
        if not prio:
            return "normal priority"
        if self.opt.speed == math.inf:  # back-to-back scans would hog a CPU at RT priority
            return "normal priority (--speed max)"
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
            if self._server is not None and prio > 1:
                self._server.set_priority(prio - 1)
        except (AttributeError, OSError) as e:
            log.warning("no real-time priority for the scan thread: %s", e)
            return (f"normal priority (real-time priority not permitted: "
                    f"{getattr(e, 'strerror', None) or e})")
        return (f"real-time priority SCHED_FIFO {prio}"
                + (f" (Modbus thread {prio - 1})" if prio > 1 else ""))

    def _loop(self, server: ServerThread) -> None:
        plc, opt = self.plc, self.opt
        clock = self.clock
        sleep = self.sleep
        state = plc.state
        now = clock()
        next_start = now
        next_stats = now + opt.stats_interval if opt.stats_interval else math.inf
        last_requests, last_stats_t = 0, now
        image = self.image
        wait_bit = opt.host_wait if opt.speed is not None else None
        virtual = opt.speed is not None
        mem_m = plc.mem.m
        held = False
        while not self._stop:
            if (wait_bit is not None and mem_m[wait_bit] and image is not None
                    and not image.pending and plc.state == RUN
                    and not (self.web is not None and self.web.controller.pending)):
                # the program waits for its host: hold the virtual clock until a write
                # (short waits: signals, stop requests and a change queued by the web
                # monitor, e.g. a force, are seen within one 0.1 s slice)
                if not held:
                    held = True
                    for hook in opt.on_host_wait:
                        hook()
                image.wait_for_write(0.1)
                next_start = clock()
                continue
            held = False
            if virtual and not build.settle_exchange(plc.machine, 0.1):
                next_start = clock()  # the virtual clock waits for the EXCH remote
                continue
            delay = next_start - clock()
            if delay > 0.1:  # long periods: stay responsive to signals
                sleep(0.1)
                continue
            if delay > 0:
                sleep(delay)
            self._scanning = True  # before the last check: request_stop then interrupts
            if self._stop:
                self._scanning = False
                break
            start = clock()
            if self.interval:
                late = start - next_start
                if opt.stats_interval:
                    self.jitter.append(late)
                if late > self.jitter_max:
                    self.jitter_max = late
            plc.scan()  # in HALT or STOP it still applies writes and refreshes the snapshot
            self._scanning = False
            if self.interrupted:
                break
            if plc.state != state:
                state = plc.state
                if state == HALT:
                    log.error("controller halted: %s", plc.fault)
                    self.say(f"controller in HALT: {plc.fault}")
            end = clock()
            next_start = self._next_start(next_start, start, end)
            sw0 = plc.mem.sw.w[0]
            if sw0 != self.period_ms:  # the program changed the period
                if MIN_PERIOD_MS <= sw0 <= MAX_PERIOD_MS:
                    log.info("program set %%SW0: period %d ms", sw0)
                    self._set_period(sw0)
                else:
                    plc.mem.sw.w[0] = self.period_ms
            if end >= next_stats or self.stats_wanted:
                self.stats_wanted = False
                req = server.stats.requests
                rate = (req - last_requests) / (end - last_stats_t)
                last_requests, last_stats_t = req, end
                next_stats = end + opt.stats_interval if opt.stats_interval else math.inf
                self.say(self._stats_line(server, rate))

    def _next_start(self, scheduled: float, start: float, end: float) -> float:
        """When the next scan starts, after a scan scheduled at `scheduled` ran from `start`
        to `end`; counts the overrun if the cycle missed its period. The catch-up rule:
        a late cycle is followed by a scan at once, and the schedule restarts from there
        (the starts that passed are skipped, not run back to back)."""
        interval = self.interval
        due = scheduled + interval
        if end <= due:
            return due
        if interval and self.opt.speed is None:  # a virtual clock's time never runs late
            passed = int((end - scheduled) / interval)  # scheduled starts passed, >= 1
            late = end - start <= interval  # the scan alone fitted: its start was late
            self.overruns += 1
            self.late_starts += late
            self.skipped_starts += passed - 1
            self.plc.engine.note_overrun(late=late, skipped=passed - 1)  # %S19, %SW33, %SW34
        return end

    def _state_kept(self, lost: str) -> None:
        """The state file cannot be kept (`lost` says why): refuse host writes, which could
        not be kept either, until it can ("")."""
        image = self.image
        if image is None:
            return
        image.refused_why = f"writes refused: {lost}" if lost else ""
        image.writes_allowed = not lost and not self.opt.read_only

    def _stats_line(self, server: ServerThread, rate: float) -> str:
        st = self.plc.stats
        p50, p99 = percentiles(self.jitter, 50, 99)
        jmax = max(self.jitter, default=0.0)
        self.jitter = []
        return (f"stats scans={st.scans} scan_last={_ms(st.last)} scan_max={_ms(st.max)} "
                f"overruns={self.overruns} late={self.late_starts} "
                f"skipped={self.skipped_starts} jitter_p50={_ms(p50)} jitter_p99={_ms(p99)} "
                f"jitter_max={_ms(jmax)} clients={server.stats.clients} req/s={rate:.0f} "
                f"exceptions={server.stats.exceptions} "
                f"refused={server.stats.rejected + server.stats.denied} state={self.plc.state}"
                + (f" web={self.web.server.url}" if self.web is not None else ""))

    def _shutdown(self, server: ServerThread, store: retain.StateStore | None,
                  keeper: StateKeeper | None) -> None:
        plc = self.plc
        for service in (self.opt.link, self.opt.wires):  # off the link and the wires
            if service is not None:  # before the outputs go to 0
                service.stop()
        plc.engine.stop_outputs()
        if self.web is not None:  # web monitor hook
            self.web.stop()
        server.stop()  # closes every client: nothing more can be acknowledged
        # The store already holds the last scan boundary and every write acknowledged since
        # (journal): flush it to disk.
        saved = ""
        if keeper is not None and store is not None:
            keeper.stop()
            try:
                if keeper.check():  # the file at the path is the store's (re-created if not)
                    store.persist()
                    saved = f", state saved to {self.opt.state}"
                else:
                    saved = f", state NOT saved: {keeper.lost}"
            except OSError as e:
                saved = f", state NOT saved: cannot flush {self.opt.state}: {e.strerror or e}"
            finally:
                store.close()
        plc.close()  # devices flush their files (the trace CSV)
        cut = ", last scan interrupted (state as of the scan before)" if self.interrupted else ""
        self.say(f"stopped after {plc.stats.scans} scans, {self.overruns} overruns "
                 f"({self.late_starts} late starts, {self.skipped_starts} starts skipped), "
                 f"jitter max {_ms(self.jitter_max)}, outputs 0{saved}{cut}")
