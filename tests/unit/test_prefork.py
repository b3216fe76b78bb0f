"""`softplc.daemon.prefork_warm_up`: what a process that forks daemons does once (the test
zygote, tests/zygote.py). It must leave nothing a fork would copy badly: no thread (a fork
keeps only the calling one) and no open file."""

from __future__ import annotations

import os
import sys
import threading

from softplc.daemon import prefork_warm_up
from softplc.devices.base import MACHINE_PLUGINS, device_types


def _fds() -> set[str]:
    return set(os.listdir("/proc/self/fd"))


def test_warm_up_starts_no_thread_opens_nothing_and_registers_the_machines_devices():
    threads, fds = threading.active_count(), _fds()
    prefork_warm_up()
    assert threading.active_count() == threads
    assert _fds() <= fds
    assert MACHINE_PLUGINS in sys.modules
    # the machines' own device types, registered by the plug-in package it imported
    assert {"stepper", "pen", "trace"} <= set(device_types())
