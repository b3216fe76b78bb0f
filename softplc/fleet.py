"""`softplc fleet`: many soft Twidos served from one process, each on its own Modbus TCP
port, for testing a SCADA, an HMI or a Modbus scanner against a hundred controllers on one
machine (issue 35).

One scan thread runs every controller on its own period (the earliest due scan first; the
daemon's catch-up rule: a late cycle is followed by a scan at once and the schedule
restarts from there, `%S19` set); one event loop in one other thread serves every port
(`ModbusTcpServer`, the daemon's server, one per controller). A controller meets its
clients only through its `ModbusImage`, as in `softplc run`: writes are applied before its
next scan, reads come from the snapshot of its last one.

What a fleet does not do that `softplc run` does: retained state, online change, the web
monitor, the Remote Link (a plant's controllers are `softplc run` daemons, or `softplc
plant run`). Each controller is cold started.
"""

from __future__ import annotations

import asyncio
import gc
import heapq
import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from softplc.daemon import SWITCH_INTERVAL, percentiles
from softplc.errors import SoftPLCError
from softplc.modbus import ModbusImage, ReadOnly
from softplc.modbus.server import ModbusTcpServer, bind_listeners, new_event_loop
from softplc.modbus.tags import host_read_only

log = logging.getLogger("softplc.fleet")

MAX_CONTROLLERS = 1000  # a bound on --count: 1000 ports, 1000 memory images
# Scan-start lateness samples kept for the percentiles: a window of this many (the
# oldest dropped), 100 controllers x 100 scans/s x 60 s
MAX_SAMPLES = 600_000


@dataclass(frozen=True)
class Member:
    """One controller of the fleet: its name, program, configuration and port."""

    name: str
    program: Path
    config: Path | None
    port: int


@dataclass
class FleetStats:
    """Scan-start lateness (s) and overruns of all controllers, since the start."""

    late: list[float] = field(default_factory=list)
    scans: int = 0
    overruns: int = 0

    def add(self, late: float) -> None:
        if len(self.late) >= MAX_SAMPLES:
            del self.late[:MAX_SAMPLES // 2]
        self.late.append(late)
        self.scans += 1


def members(programs: list[tuple[Path, Path | None]], count: int,
            ports: list[int]) -> list[Member]:
    """`count` controllers running the programs in turn, on `ports` (one each)."""
    if not 1 <= count <= MAX_CONTROLLERS:
        raise SoftPLCError(f"a fleet has 1 .. {MAX_CONTROLLERS} controllers, not {count}")
    chosen = [p for p in ports if p]  # 0: any free port, each its own
    if len(ports) != count or len(set(chosen)) != len(chosen):
        raise SoftPLCError(f"{count} controllers need {count} distinct ports "
                           f"({len(ports)} given, {len(chosen) - len(set(chosen))} twice)")
    out = []
    for i in range(count):
        program, config = programs[i % len(programs)]
        out.append(Member(f"plc{i + 1}", program, config, ports[i]))
    return out


class Fleet:
    """The controllers, their servers, the scan thread."""

    def __init__(self, fleet: list[Member], host: str = "127.0.0.1", *,
                 period: float | None = None, rt_priority: int = 0,
                 max_clients: int = 4, out: TextIO | None = None):
        from softplc.plc import PLC

        self.members = fleet
        self.host = host
        self.rt_priority = rt_priority
        self.out = out or sys.stdout
        self.plcs: list[Any] = []
        self.images: list[ModbusImage] = []
        self.periods: list[float] = []
        for m in fleet:
            plc = PLC.from_file(m.program, m.config, clock="real")
            p = period if period is not None else plc.settings.scan_period
            plc.set_scan_period(p)
            plc.cold_start()
            ro, device_words = host_read_only(plc)
            device_ro = tuple(r for ranges in device_words.values() for r in ranges)
            image = ModbusImage(plc.mem, ReadOnly(ro.registers + device_ro, ro.coils))
            plc.before_scan.append(image.apply_writes)
            plc.after_scan.append(image.take_snapshot)
            image.take_snapshot()
            self.plcs.append(plc)
            self.images.append(image)
            self.periods.append(p)
        self.servers: list[ModbusTcpServer] = []
        sockets = []
        try:
            for m in fleet:
                sockets.append(bind_listeners(host, m.port))
        except OSError as e:
            for s in (s for group in sockets for s in group):
                s.close()
            raise SoftPLCError(f"cannot listen on {host}:{fleet[len(sockets)].port}: "
                               f"{e.strerror or e}") from None
        for image, socks in zip(self.images, sockets, strict=True):
            self.servers.append(ModbusTcpServer(image, host, 0, sockets=socks,
                                                max_clients=max_clients))
        self.stats = FleetStats()
        self._stop = threading.Event()
        self.loop = new_event_loop()
        self._net = threading.Thread(target=self._serve, name="fleet-modbus", daemon=True)
        self._ready = threading.Event()

    @property
    def ports(self) -> list[int]:
        return [s.sockets[0].getsockname()[1] for s in self.servers]

    # -- the Modbus thread -----------------------------------------------------------------
    def _serve(self) -> None:
        asyncio.set_event_loop(self.loop)

        async def start() -> None:
            for s in self.servers:
                await s.start()
        self.loop.run_until_complete(start())
        self._ready.set()
        self.loop.run_forever()

        async def close() -> None:
            for s in self.servers:
                await s.close()
        self.loop.run_until_complete(close())
        self.loop.close()

    # -- the scan thread -------------------------------------------------------------------
    def run(self, seconds: float | None = None,
            on_started: Callable[[Fleet], None] | None = None) -> FleetStats:
        """Serve and scan until `stop()` (or `seconds` pass); the statistics."""
        self._net.start()
        self._ready.wait()
        old_switch = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL)  # the daemon's reason: GIL hand-over latency
        gc.collect()
        gc.freeze()  # the fleet lives as long as the process: out of the collector's walks
        try:
            prio = self._realtime()
            for m, p in zip(self.members, self.ports, strict=True):
                self.say(f"  {m.name} {m.program} on {self.host}:{p}")
            # the last banner line: tools and tests wait for it
            self.say(f"softplc fleet: {len(self.plcs)} controllers serving on {self.host} "
                     f"ports {_ranges(self.ports)}; scan thread {prio}")
            if on_started is not None:
                on_started(self)
            self._loop(time.perf_counter() + seconds if seconds is not None else None)
        finally:
            sys.setswitchinterval(old_switch)
            gc.unfreeze()
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._net.join(5)
            for plc in self.plcs:
                plc.engine.stop_outputs()
                plc.close()
        return self.stats

    def _realtime(self) -> str:
        """SCHED_FIFO for the scan thread and, one below, the Modbus thread (the daemon's
        reasons: wake-ups on time on a busy machine; no priority inversion on the GIL)."""
        prio = self.rt_priority
        if not prio:
            return "normal priority"
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
        except (AttributeError, OSError) as e:
            return f"normal priority (real-time priority not permitted: {e})"
        if prio > 1:
            self.loop.call_soon_threadsafe(
                os.sched_setscheduler, 0, os.SCHED_FIFO, os.sched_param(prio - 1))
        return f"real-time priority SCHED_FIFO {prio}"

    def stop(self) -> None:
        self._stop.set()

    def _loop(self, end: float | None) -> None:
        clock = time.perf_counter
        start = clock()
        periods = self.periods
        # the starts spread over the period, not all at once: a scan due is not queued
        # behind the 99 others due at the same instant
        n = len(self.plcs)
        due = [(start + periods[i] * i / n, i) for i in range(n)]
        heapq.heapify(due)
        stats, plcs, stop = self.stats, self.plcs, self._stop
        while not stop.is_set():
            at, i = due[0]
            if end is not None and at >= end:
                break
            delay = at - clock()
            if delay > 0:
                if stop.wait(delay):  # wakes at once on stop()
                    break
            now = clock()
            stats.add(now - at)
            plcs[i].scan()
            fin = clock()
            nxt = at + periods[i]
            if fin > nxt:  # the daemon's catch-up rule: no back-to-back make-up scans
                stats.overruns += 1
                plcs[i].engine.note_overrun(late=fin - now <= periods[i],
                                            skipped=int((fin - at) / periods[i]) - 1)
                nxt = fin
            heapq.heapreplace(due, (nxt, i))

    def summary(self) -> str:
        p50, p99 = percentiles(self.stats.late, 50, 99)
        worst = max(self.stats.late, default=0.0)
        requests = sum(s.stats.requests for s in self.servers)
        return (f"fleet stats controllers={len(self.plcs)} scans={self.stats.scans} "
                f"overruns={self.stats.overruns} late_p50={p50 * 1000:.3f}ms "
                f"late_p99={p99 * 1000:.3f}ms late_max={worst * 1000:.3f}ms "
                f"requests={requests}")

    def say(self, text: str) -> None:
        print(text, file=self.out, flush=True)


def _ranges(ports: list[int]) -> str:
    """5100-5199 for consecutive ports, else "as listed above"."""
    if ports == list(range(ports[0], ports[0] + len(ports))):
        return f"{ports[0]}-{ports[-1]}" if len(ports) > 1 else str(ports[0])
    return "as listed above"
