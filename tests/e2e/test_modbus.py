"""The Modbus TCP server over real loopback sockets, against a bare memory image.

A stub scan (`scan()` below) stands in for the engine: apply queued writes, run a tiny
"program", take the read snapshot, exactly the hooks the daemon installs on the PLC.
"""

from __future__ import annotations

import logging
import os
import shutil
import socket
import struct
import subprocess
import threading
import time

import pytest
from modbus_util import closed_or_reply
from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse
from pyModbusTCP.client import ModbusClient

from softplc.config import validate_config
from softplc.modbus import ModbusImage, ReadOnly, ServerThread, read_only_of
from softplc.modbus.rawclient import RawClient
from softplc.modbus.regmap import DEVICE_IDENTIFICATION, FUNCTIONS, describe, markdown_table
from softplc.modbus_codec import frame as mbap_frame
from softplc.runtime.memory import MemoryImage

logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
logging.getLogger("softplc.modbus").setLevel(logging.CRITICAL)

READ_ONLY = ReadOnly(registers=((100, 110),), coils=((200, 208),))


class Rig:
    """A memory image, its Modbus view and a server on a free loopback port."""

    def __init__(self, **server_options):
        self.mem = MemoryImage()
        self.img = ModbusImage(self.mem, READ_ONLY)
        self.server = ServerThread(self.img, "127.0.0.1", 0, **server_options).start()
        self.port = self.server.port
        self.scans = 0

    def scan(self) -> None:
        """Stub scan: queued writes in, the 'program' (%MW1 := %MW0 + 1), snapshot out."""
        self.img.apply_writes()
        self.mem.mw.w[1] = self.mem.mw.w[0] + 1
        self.scans += 1
        self.img.take_snapshot()

    def raw(self, timeout: float = 2.0) -> RawClient:
        return RawClient("127.0.0.1", self.port, timeout)


@pytest.fixture
def rig():
    r = Rig(frame_timeout=0.3)
    yield r
    r.server.stop()


def exc(fc: int, code: int) -> bytes:
    return bytes((fc | 0x80, code))


# -- every function code through pymodbus ---------------------------------------------------
def test_pymodbus_every_function(rig):
    mem = rig.mem
    mem.mw.w[5] = -2
    mem.m[3] = 1
    mem.mw.set_f(40, 1.5)
    rig.scan()
    c = ModbusTcpClient("127.0.0.1", port=rig.port, timeout=2)
    assert c.connect()
    try:
        assert c.read_holding_registers(4, count=3).registers == [0, 0xFFFE, 0]
        assert c.read_input_registers(5, count=1).registers == [0xFFFE]
        # %MF40 = registers 40 (low word) and 41 (high word)
        r = c.read_holding_registers(40, count=2).registers
        assert struct.unpack("<f", struct.pack("<HH", *r))[0] == 1.5
        assert c.read_coils(0, count=5).bits[:5] == [False, False, False, True, False]
        assert c.read_discrete_inputs(3, count=1).bits[0] is True

        w = c.write_register(7, 1234)
        assert (w.address, w.registers) == (7, [1234])  # echo
        w = c.write_coil(9, True)
        assert (w.address, w.bits[0]) == (9, True)
        assert not c.write_registers(20, [1, 2, 3]).isError()
        assert not c.write_coils(30, [True, False, True]).isError()
        rw = c.readwrite_registers(read_address=5, read_count=1, write_address=50,
                                   values=[77, 78])
        assert rw.registers == [0xFFFE]
        # Nothing reaches the image before the next scan...
        assert mem.mw.w[7] == 0 and mem.m[9] == 0 and mem.mw.w[50] == 0
        # ...but hosts read back their own writes at once, as between two Twido scans.
        assert c.read_holding_registers(7, count=1).registers == [1234]
        rig.scan()
        # ...and everything at it.
        assert list(mem.mw.w[20:23]) == [1, 2, 3] and mem.mw.w[7] == 1234
        assert list(mem.m[30:33]) == [1, 0, 1] and mem.m[9] == 1
        assert list(mem.mw.w[50:52]) == [77, 78]
        assert c.read_holding_registers(20, count=3).registers == [1, 2, 3]

        info = c.read_device_information()
        assert info.information == DEVICE_IDENTIFICATION
        for unit in (0, 1, 255, 42):  # any unit id is accepted and echoed
            r = c.read_device_information(device_id=unit)
            assert not r.isError() and r.dev_id == unit
            assert r.information[1] == b"TWDLCAE40DRF"

        e = c.read_holding_registers(2999, count=2)
        assert isinstance(e, ExceptionResponse) and e.exception_code == 2
        e = c.write_register(105, 1)
        assert isinstance(e, ExceptionResponse) and e.exception_code == 2
    finally:
        c.close()


# -- every function code through an independent client -----------------------------------
def test_pymodbustcp_every_function(rig):
    rig.mem.mw.w[0] = 41
    rig.mem.m[0] = 1
    rig.scan()
    c = ModbusClient(host="127.0.0.1", port=rig.port, unit_id=9, timeout=2)
    try:
        assert c.read_holding_registers(0, 2) == [41, 42]
        assert c.read_input_registers(1, 1) == [42]
        assert c.read_coils(0, 2) == [True, False]
        assert c.read_discrete_inputs(0, 1) == [True]
        assert c.write_single_register(0, 99)
        assert c.write_single_coil(1, True)
        assert c.write_multiple_registers(10, [5, 6])
        assert c.write_multiple_coils(20, [True, True, False, True])
        assert c.write_read_multiple_registers(12, [7], 0, 2) == [99, 42]  # %MW0 written
        rig.scan()
        assert c.read_holding_registers(0, 2) == [99, 100]  # the program saw %MW0 = 99
        assert c.read_holding_registers(10, 3) == [5, 6, 7]
        assert c.read_coils(0, 2) == [True, True]
        assert c.read_coils(20, 4) == [True, True, False, True]
        dev = c.read_device_identification(1)
        assert dev.objects_by_id == DEVICE_IDENTIFICATION
        assert c.read_holding_registers(3000, 1) is None and c.last_except == 2
        assert c.write_single_coil(203, True) is False and c.last_except == 2
    finally:
        c.close()


# -- mbpoll (Debian), skipped only if the binary is missing --------------------------------
MBPOLL = shutil.which("mbpoll")


def mbpoll(port: int, *args: str) -> str:
    out = subprocess.run([MBPOLL, "-m", "tcp", "-p", str(port), "-0", "-1", "-o", "2", *args],
                         capture_output=True, text=True, timeout=10)
    assert out.returncode == 0, out.stdout + out.stderr
    return out.stdout


def mbpoll_values(text: str) -> dict[int, str]:
    vals = {}
    for line in text.splitlines():
        if line.startswith("["):
            ref, _, v = line.partition(":")
            vals[int(ref.strip("[] "))] = v.strip()
    return vals


@pytest.mark.skipif(MBPOLL is None, reason="mbpoll is not installed")
def test_mbpoll_every_function(rig):
    rig.mem.mw.set_f(40, -2.25)
    rig.mem.mw.set_d(44, 123456)
    rig.scan()
    host = "127.0.0.1"
    assert mbpoll_values(mbpoll(rig.port, "-t", "4:float", "-r", "40", host)) == {40: "-2.25"}
    assert mbpoll_values(mbpoll(rig.port, "-t", "3:int", "-r", "44", host)) == {44: "123456"}
    mbpoll(rig.port, "-t", "4", "-r", "10", host, "11")  # FC 6
    mbpoll(rig.port, "-t", "4", "-r", "20", host, "1", "2", "3")  # FC 16
    mbpoll(rig.port, "-t", "0", "-r", "5", host, "1")  # FC 5
    mbpoll(rig.port, "-t", "0", "-r", "8", host, "1", "0", "1")  # FC 15
    rig.scan()
    assert mbpoll_values(mbpoll(rig.port, "-t", "4", "-r", "20", "-c", "3", host)) == \
        {20: "1", 21: "2", 22: "3"}
    assert mbpoll_values(mbpoll(rig.port, "-t", "3", "-r", "10", host)) == {10: "11"}
    assert mbpoll_values(mbpoll(rig.port, "-t", "0", "-r", "8", "-c", "3", host)) == \
        {8: "1", 9: "0", 10: "1"}
    assert mbpoll_values(mbpoll(rig.port, "-t", "1", "-r", "5", "-a", "255", host)) == {5: "1"}


# -- exception codes, byte for byte ---------------------------------------------------------
@pytest.mark.parametrize("pdu, reply", [
    (b"\x07", exc(7, 1)),  # unsupported function
    (b"\x08\x00\x00\x00\x00", exc(8, 1)),
    (b"\x41\x00", exc(0x41, 1)),
    (b"\x2b\x0d\x01\x00", exc(43, 1)),  # MEI 13 (CANopen)
    (struct.pack(">BHH", 3, 0, 0), exc(3, 3)),  # zero quantity
    (struct.pack(">BHH", 3, 0, 126), exc(3, 3)),
    (struct.pack(">BHH", 4, 0, 126), exc(4, 3)),
    (struct.pack(">BHH", 1, 0, 2001), exc(1, 3)),
    (struct.pack(">BHH", 2, 0, 0), exc(2, 3)),
    (struct.pack(">BHH", 3, 2990, 11), exc(3, 2)),  # past %MW2999
    (struct.pack(">BHH", 3, 2990, 10), None),
    (struct.pack(">BHH", 1, 250, 7), exc(1, 2)),  # past %M255
    (struct.pack(">BHH", 5, 256, 0xFF00), exc(5, 2)),
    (struct.pack(">BHH", 5, 1, 0x1234), exc(5, 3)),  # coil value neither FF00 nor 0000
    (struct.pack(">BHH", 5, 203, 0xFF00), exc(5, 2)),  # read-only %M200..207
    (struct.pack(">BHH", 6, 3000, 1), exc(6, 2)),
    (struct.pack(">BHH", 6, 109, 1), exc(6, 2)),  # read-only %MW100..109
    (struct.pack(">BHH", 6, 110, 1), bytes(struct.pack(">BHH", 6, 110, 1))),
    (struct.pack(">BHHB", 16, 0, 124, 246) + bytes(246), exc(16, 3)),  # 124 > 123
    (struct.pack(">BHHB", 16, 0, 0, 0), exc(16, 3)),
    (struct.pack(">BHHB2H", 16, 0, 2, 3, 1, 2), exc(16, 3)),  # byte count mismatch
    (struct.pack(">BHHB", 16, 0, 2, 4) + b"\x00\x01\x00", exc(16, 3)),  # short data
    (struct.pack(">BHHB2H", 16, 99, 2, 4, 1, 2), exc(16, 2)),  # ends in read-only
    (struct.pack(">BHHB2H", 16, 2999, 2, 4, 1, 2), exc(16, 2)),
    (struct.pack(">BHHB", 15, 0, 1969, 247) + bytes(247), exc(15, 3)),
    (struct.pack(">BHHBB", 15, 0, 9, 1, 0xFF), exc(15, 3)),  # 9 coils need 2 bytes
    (struct.pack(">BHHBB", 15, 207, 1, 1, 1), exc(15, 2)),
    (struct.pack(">BHHBB", 15, 255, 2, 1, 3), exc(15, 2)),
    (struct.pack(">BHHHHBH", 23, 0, 126, 0, 1, 2, 5), exc(23, 3)),
    (struct.pack(">BHHHHB", 23, 0, 1, 0, 122, 242) + bytes(242), exc(23, 3)),
    (struct.pack(">BHHHHBH", 23, 0, 1, 100, 1, 2, 5), exc(23, 2)),
    (struct.pack(">BHHHHBH", 23, 2999, 2, 0, 1, 2, 5), exc(23, 2)),
    (b"\x03\x00\x00\x00", exc(3, 3)),  # truncated PDU
    (b"\x03\x00\x00\x00\x01\x00", exc(3, 3)),  # trailing byte
    (b"\x06\x00", exc(6, 3)),
    (b"\x2b", exc(43, 1)),
    (b"\x2b\x0e\x05\x00", exc(43, 3)),  # bad read device id code
    (b"\x2b\x0e\x04\x07", exc(43, 2)),  # individual access to an absent object
    (b"\x2b\x0e\x04\x01", b"\x2b\x0e\x04\x81\x00\x00\x01\x01\x0cTWDLCAE40DRF"),
])
def test_exception_codes(rig, pdu, reply):
    with rig.raw() as c:
        resp = c.request(pdu, unit=255)
        if reply is None:
            assert resp[0] == pdu[0] and not resp[0] & 0x80
        else:
            assert resp == reply
        # the connection is still good afterwards
        assert c.read_registers(0, 1) == [0]
    assert rig.mem.mw.w[109] == 0 and rig.mem.m[203] == 0


def test_limits_accepted(rig):
    """The maximum quantities themselves are fine."""
    with rig.raw() as c:
        assert len(c.read_registers(0, 125)) == 125
        assert c.call(struct.pack(">BHH", 1, 0, 256))[1] == 32
        c.write_registers(200, list(range(123)))
        c.call(struct.pack(">BHHB", 15, 0, 200, 25) + b"\xff" * 25)
        c.call(struct.pack(">BHHHHB", 23, 0, 1, 400, 121, 242) + bytes(242))
    rig.scan()
    assert list(rig.mem.mw.w[200:323]) == list(range(123))
    assert sum(rig.mem.m[:200]) == 200


def test_device_identification_stream(rig):
    with rig.raw() as c:
        for code in (1, 2, 3):
            r = c.call(bytes((43, 14, code, 0)))
            assert r[:7] == bytes((43, 14, code, 0x81, 0, 0, 3))
            assert b"TELEMECANIQUE" in r and b"05.40" in r
        r = c.call(bytes((43, 14, 1, 2)))  # start at object 2
        assert r[6] == 1 and r.endswith(b"\x02\x0505.40")
        r = c.call(bytes((43, 14, 1, 9)))  # unknown start object: restart at 0
        assert r[6] == 3


def test_pipelined_requests_and_unit_echo(rig):
    rig.mem.mw.w[3] = 7
    rig.scan()
    with rig.raw() as c:
        frames = b"".join(mbap_frame(100 + k, k, struct.pack(">BHH", 3, 3, 1)) for k in range(5))
        c.sock.sendall(frames)
        for k in range(5):
            tid, unit, pdu = c.recv_frame()
            assert (tid, unit, pdu) == (100 + k, k, b"\x03\x02\x00\x07")


# -- consistency ----------------------------------------------------------------------------
def test_write_seen_at_next_scan_not_earlier(rig):
    rig.scan()
    with rig.raw() as c:
        c.write_registers(0, [500])
        assert rig.mem.mw.w[0] == 0 and rig.img.pending == 1
        # the host reads its write back; %MW1 (the program's %MW0 + 1) waits for a scan
        assert c.read_registers(0, 2) == [500, 1]
        rig.scan()
        assert c.read_registers(0, 2) == [500, 501]


def test_fc16_frames_land_whole_while_scanning():
    """A scan thread checks that %MW0..%MW99 are always equal while a client writes frames
    of 100 equal values as fast as it can: no scan ever sees half a frame."""
    r = Rig()
    torn = []
    stop = threading.Event()

    def scanner():
        while not stop.is_set():
            r.img.apply_writes()
            w = bytes(r.mem.mw.buf[:200])
            if w != w[:2] * 100:
                torn.append(w)
            r.img.take_snapshot()
            time.sleep(0.0002)

    t = threading.Thread(target=scanner)
    t.start()
    try:
        with r.raw() as c:
            for k in range(300):
                c.write_registers(0, [k] * 100)
                regs = c.read_registers(0, 100)
                assert len(set(regs)) == 1  # snapshots are whole too
    finally:
        stop.set()
        t.join()
        r.server.stop()
    assert not torn
    r.img.apply_writes()
    assert r.img.writes_applied == 300


# -- malformed traffic ---------------------------------------------------------------------
def test_malformed_traffic_keeps_server_serving(rig):
    good = rig.raw()
    good.write_registers(0, [1])
    silent = socket.create_connection(("127.0.0.1", rig.port))  # connects, sends nothing

    cases = {
        "MBAP length longer than the data": mbap_frame(1, 1, b"\x03\x00\x00\x00\x01")[:-2],
        "MBAP length 0": b"\x00\x01\x00\x00\x00\x00\x01\x03",
        "MBAP length 1 (no function code)": b"\x00\x01\x00\x00\x00\x01\x01",
        "MBAP length beyond 254": b"\x00\x01\x00\x00\x01\x00\x01" + bytes(300),
        "protocol id not 0": b"\x00\x01\x00\x07\x00\x06\x01\x03\x00\x00\x00\x01",
        "random bytes": bytes(range(7, 200, 3)) + os.urandom(64),
    }
    for name, data in cases.items():
        s = socket.create_connection(("127.0.0.1", rig.port))
        s.sendall(data)
        assert closed_or_reply(s) == b"", name
        s.close()
        assert good.read_registers(0, 1) == [1], name  # served in between

    # A truncated PDU inside a correct frame gets an exception reply.
    s = socket.create_connection(("127.0.0.1", rig.port))
    s.sendall(mbap_frame(9, 3, b"\x10\x00\x00"))
    assert closed_or_reply(s) == mbap_frame(9, 3, exc(16, 3))
    # A client that disconnects mid-frame.
    s.sendall(mbap_frame(10, 3, struct.pack(">BHHB2H", 16, 0, 2, 4, 9, 9))[:-3])
    s.close()
    # Zero quantity and unknown function: exception replies on a raw socket.
    with rig.raw() as c:
        assert c.request(struct.pack(">BHH", 15, 0, 0)) == exc(15, 3)
        assert c.request(b"\x5a\x01\x02") == exc(0x5A, 1)

    good.write_registers(1, [2])
    rig.scan()
    assert good.read_registers(0, 2) == [1, 2]  # nothing lost, nothing partial applied
    assert rig.img.writes_applied == 2
    # The silent client is still connected and can be served too.
    silent.sendall(mbap_frame(1, 1, struct.pack(">BHH", 3, 0, 1)))
    assert closed_or_reply(silent) == mbap_frame(1, 1, b"\x03\x02\x00\x01")
    silent.close()
    good.close()
    assert rig.server.stats.dropped >= len(cases)


def test_idle_timeout_counts_requests_not_bytes():
    r = Rig(idle_timeout=0.3)
    try:
        a = socket.create_connection(("127.0.0.1", r.port))  # silent
        d = socket.create_connection(("127.0.0.1", r.port))  # sends a byte now and then
        with r.raw() as b:
            for _ in range(12):  # b keeps talking for 0.6 s, a stays silent, d drips
                assert b.read_registers(0, 1) == [0]
                try:
                    d.send(b"\x00")
                except OSError:  # closed by the server: the assert below sees it
                    pass
                time.sleep(0.05)
            assert closed_or_reply(a) == b""
            assert closed_or_reply(d) == b""  # bytes of an unfinished frame are no activity
            assert b.read_registers(0, 1) == [0]
        a.close()
        d.close()
    finally:
        r.server.stop()


# -- the map table --------------------------------------------------------------------------
def test_map_table_and_read_only_config():
    assert set(FUNCTIONS) == {1, 2, 3, 4, 5, 6, 15, 16, 23, 43}
    ro = read_only_of(validate_config(
        {"modbus": {"read_only": ["%MW100:10", "%MF200", "%M8:4", "%M0"]}}).modbus.read_only)
    assert ro.registers == ((100, 110), (200, 202)) and ro.coils == ((8, 12), (0, 1))
    assert ro.blocks("registers", 95, 5) is False and ro.blocks("registers", 95, 6) is True
    assert "| 16 | Write Multiple Registers | %MWn | 123 |" in markdown_table()
    assert any("read-only registers: %MW100..%MW109" in line for line in describe(3000, 256, ro))


def test_client_that_never_reads_replies_is_reset(rig):
    """Pipelined requests with no reads: once the replies fill the kernel's buffers and
    the server's bounded write buffer, the client is reset (its slot freed, memory
    bounded) and the others are served."""
    s = socket.create_connection(("127.0.0.1", rig.port))
    frame = mbap_frame(1, 1, struct.pack(">BHH", 3, 0, 125))  # 12 bytes in, 259 out
    s.setblocking(False)
    sent, reset = 0, False
    end = time.monotonic() + 5
    while time.monotonic() < end:
        try:
            sent += s.send(frame * 1000)
        except BlockingIOError:
            time.sleep(0.01)
        except OSError:  # reset by the server
            reset = True
            break
    assert reset and sent < 20_000_000  # reset once the buffers were full, not later
    assert not rig.server.server.connections and rig.server.stats.dropped == 1
    with rig.raw() as c:
        assert c.read_registers(0, 1) == [0]
    s.close()


# -- both event loops (issue 26: uvloop when installed, asyncio on request) -----------------
@pytest.mark.parametrize("loop", ["default", "asyncio"])
def test_both_event_loops_serve_writes_and_reads(monkeypatch, loop):
    """FC 16 of 100 registers is read back at once (before any scan), lands in %MW at the
    next scan start in one piece, and coils likewise, with either event loop."""
    monkeypatch.setenv("SOFTPLC_EVENT_LOOP", loop)
    r = Rig()
    try:
        kind = type(r.server.loop).__module__
        if loop == "asyncio":
            assert kind.startswith("asyncio")
        else:
            uvloop = pytest.importorskip("uvloop")
            assert isinstance(r.server.loop, uvloop.Loop)
        values = [(i * 517) & 0xFFFF for i in range(100)]
        with r.raw() as c:
            c.write_registers(300, values)
            assert c.read_registers(300, 100) == values  # the pending write, read back
            assert c.read_registers(299, 1) == [0]
            assert r.mem.mw.w[300] == 0  # not applied before the scan
            c.call(struct.pack(">BHHB", 15, 20, 4, 1) + bytes((0b1101,)))  # coils 20-23
            r.scan()
            assert [r.mem.mw.w[300 + i] & 0xFFFF for i in range(100)] == values
            assert [r.mem.m[20 + i] for i in range(4)] == [1, 0, 1, 1]
            c.write_registers(350, [7])  # a second write over the same range
            r.scan()
            assert c.read_registers(349, 3) == [values[49], 7, values[51]]
    finally:
        r.server.stop()
