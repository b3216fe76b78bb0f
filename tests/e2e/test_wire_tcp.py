"""A controller's wires over TCP (softplc.access.wires, softplc.runtime.wiretcp; issue 35):
the plant host drives the wired inputs through the access port's queue and reads the
wired outputs; only its address may connect; a broken wire (connection lost, or silent
for the hold time) reads 0; a client of another layout is cut off."""

from __future__ import annotations

import socket
import time

import pytest
from waits import WAIT_S

from softplc.access import AccessPort
from softplc.access.errors import AccessError
from softplc.access.wires import WireService, wired_refs
from softplc.plc import PLC
from softplc.runtime.wiretcp import OUTPUTS, SET, WireClient, encode, layout

IL = "LD %I0.0\nST %Q0.1\nLD %I0.2\nST %Q0.3\n"
INS, OUTS = ["%I0.0", "%I0.2"], ["%Q0.1"]
HOLD_S = 0.3  # short here: the silent case ends quickly


@pytest.fixture
def wired():
    plc = PLC.from_source(IL)
    svc = WireService("127.0.0.1", 0, "127.0.0.1", INS, OUTS, hold_s=HOLD_S)
    access = AccessPort(plc)
    svc.attach_access(plc, access)
    svc.start()
    yield plc, svc, access
    svc.stop()
    access.close()
    plc.close()


def _scan_until(plc: PLC, cond, timeout: float = WAIT_S) -> bool:
    """Scan (the queue is applied at each boundary) until cond() holds."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        plc.scan()
        if cond():
            return True
        time.sleep(0.01)
    return False


def _closed(s: socket.socket) -> bool:
    """The other end closed the connection (a reset when our bytes were left unread)."""
    try:
        return s.recv(64) == b""
    except ConnectionResetError:
        return True


def test_the_plant_host_drives_inputs_through_the_queue_and_reads_outputs(wired):
    plc, svc, access = wired
    client = WireClient("t", svc.address, INS, OUTS)
    assert client.exchange([True, False]) == (False,)  # the outputs of the last scan
    assert plc["%I0.0"] == 0  # not yet: applied at the next scan boundary
    assert _scan_until(plc, lambda: plc["%Q0.1"] == 1)
    assert access.queue.applied >= 1  # it went through the one command queue
    assert client.exchange([True, False]) == (True,)
    # the monitor may not write a wired input (force it, yes); an unwired one it may
    with pytest.raises(AccessError, match="plant host's wire"):
        access.write_many([("%I0.0", 0)])
    access.write_many([("%I0.1", 1)])
    # the plant host goes (its connection ends): the wired inputs fall to 0
    client.close()
    assert _scan_until(plc, lambda: plc["%I0.0"] == 0 and plc["%Q0.1"] == 0)
    assert plc["%I0.1"] == 1


def test_a_silent_plant_host_is_a_broken_wire_after_the_hold_time(wired):
    plc, svc, _ = wired
    with socket.create_connection(svc.address) as s:
        s.sendall(encode(SET, svc.layout, [True, True]))
        s.recv(64)
        assert _scan_until(plc, lambda: plc["%I0.2"] == 1 and plc["%Q0.3"] == 1)
        # nothing more is sent: after HOLD_S the inputs read 0 and the connection ends
        assert _scan_until(plc, lambda: plc["%I0.2"] == 0 and plc["%I0.0"] == 0)
        assert _closed(s)
    assert svc.breaks >= 1


def test_only_the_plant_hosts_address_may_connect():
    plc = PLC.from_source(IL)
    svc = WireService("127.0.0.1", 0, "127.0.0.2", INS, OUTS)  # the plant host elsewhere
    access = AccessPort(plc)
    svc.attach_access(plc, access)
    svc.start()
    try:
        client = WireClient("t", svc.address, INS, OUTS)
        assert client.exchange([True, True]) is None  # closed before a byte was read
        assert _scan_until(plc, lambda: svc.refused >= 1)
        plc.scan(3)
        assert plc["%I0.0"] == 0 and svc.frames == 0
    finally:
        svc.stop()
        access.close()
        plc.close()


def test_a_client_of_another_layout_or_a_bad_frame_is_cut_off(wired):
    plc, svc, _ = wired
    other = WireClient("t", svc.address, ["%I0.2", "%I0.0"], OUTS)  # another order
    assert other.exchange([True, True]) is None
    for bad in (b"XX" + encode(SET, svc.layout, [True, True])[2:],
                encode(OUTPUTS, svc.layout, [True, True]),
                encode(SET, svc.layout, [True, True])[:-1] + b"\x07"):
        with socket.create_connection(svc.address) as s:
            s.settimeout(WAIT_S)
            s.sendall(bad)
            assert _closed(s)  # nothing answered
    plc.scan(3)
    assert plc["%I0.0"] == 0 and plc["%I0.2"] == 0


def test_the_wired_lists_are_checked():
    assert [str(r) for r in wired_refs(["%I0.0", "%I1.3"], "I", "--wire-in")] == \
        ["%I0.0", "%I1.3"]
    for bad, why in ((["%Q0.0"], "not a %I bit"), (["%I0.0", "%I0.0"], "twice"),
                     (["%MW0"], "not a %I bit"), ([f"%I0.{k}" for k in range(65)], "at most")):
        with pytest.raises(ValueError, match=why):
            wired_refs(bad, "I", "--wire-in")
    assert layout(INS, OUTS) != layout(list(reversed(INS)), OUTS)
