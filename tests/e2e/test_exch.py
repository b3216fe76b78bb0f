"""EXCH3 / %MSG3: the Twido as a Modbus TCP client (issue 11 B, runtime/exch.py).

The table layouts are the Twido's Modbus master tables [manual: TWD USE 10AE, "Modbus
master", from memory: see docs/twido.md#exch-and-msg]: word 0 = command
(high byte) | transmission length in bytes, word 1 = reception offset | transmission
offset, then the transmission table, then the reception table. All run on the virtual
clock: the reply lands at the first scan boundary after the request (deterministic).
"""

from __future__ import annotations

import signal
import socket
import sys
import threading
import time
import tomllib
from pathlib import Path

import pytest
from daemon_util import started
from modbus_util import PymodbusThread, refused_port
from pymodbus.simulator import DataType, SimData, SimDevice

from softplc.errors import ConfigError, ProgramError
from softplc.il.parser import parse
from softplc.il.printer import format_program
from softplc.plc import PLC
from softplc.runtime import exch

EXAMPLES = Path(__file__).resolve().parents[2] / "ladder_programs"
sys.path.insert(0, str(EXAMPLES.parent / "tools"))

import bench_exch  # noqa: E402
from bench_exch import Dripper  # noqa: E402


def config(port: int, timeout: str = "300ms", **more) -> dict:
    return {"exch": {"timeout": timeout,
                     "remote": {"1": {"host": "127.0.0.1", "port": port, "unit_id": 1}}},
            **more}


class PymodbusServer(PymodbusThread):
    """An independent Modbus TCP server (pymodbus): registers 0..19 = 100..119."""

    def device(self) -> SimDevice:
        return SimDevice(id=1, simdata=[
            SimData(0, count=20, values=[100 + k for k in range(20)],
                    datatype=DataType.REGISTERS)])


@pytest.fixture
def silent_port():
    """A port where a server accepts connections and never answers."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        yield silent.getsockname()[1]


# One exchange on request: %M0 starts it (the program tests %MSG3.D, as the manual says).
ONE_SHOT = """
LD     %M0
AND    %MSG3.D
EXCH3  %MW0:{n}
R      %M0
"""


def run_table(plc: PLC, words: list[int], n: int, scans: int = 1) -> None:
    for k, v in enumerate(words):
        plc.mem.mw.w[k] = v - 0x10000 if v & 0x8000 else v
    plc.force("%M0", 1)
    plc.scan()
    plc.unforce("%M0")
    plc["%M0"] = 0
    plc.scan(scans)


# remote 1, FC03: read the word at address 0 (Tx 6 bytes, Rx offset 3)
READ_WORD_0 = [0x0106, 0x0300, 0x0103, 0, 1]


def finish(plc: PLC) -> tuple[int, float]:
    """Scan until the exchange in progress is done (%MSG3.D): the scans and PLC seconds."""
    first, t0 = plc.scan_count, plc.time
    while not plc["%MSG3.D"]:
        plc.scan()
    return plc.scan_count - first, plc.time - t0


def u(plc: PLC, a: int) -> int:
    return plc.mem.mw.w[a] & 0xFFFF


def test_read_write_words_against_pymodbus():
    # FC16 write 2 words, then FC03 read them back [manual: "write N words" / "read N words"]
    with PymodbusServer() as srv:
        plc = PLC.from_source(ONE_SHOT.format(n=12), config(srv.port))
        # FC16: Tx 8 + 2N = 12 bytes, Tx offset 7 (the byte-count word's padding byte)
        run_table(plc, [0x010C, 0x0007, 0x0110, 3, 2, 0x0004, 1234, 0xBEEF], 12)
        assert plc["%MSG3.D"] and not plc["%MSG3.E"] and plc["%SW65"] == 0
        # reply in the reception table from word 2 + 6 = 8: index | FC, address, N
        assert [u(plc, 8), u(plc, 9), u(plc, 10)] == [0x0110, 3, 2]
        # FC03 read 3 words at 2: Tx 6 bytes, Rx offset 3
        run_table(plc, [0x0106, 0x0300, 0x0103, 2, 3], 12)
        assert not plc["%MSG3.E"]
        assert [u(plc, 5), u(plc, 6)] == [0x0103, 0x0006]  # index | FC, 00 | byte count
        assert [u(plc, 7), u(plc, 8), u(plc, 9)] == [102, 1234, 0xBEEF]
        # FC06 write one word [manual: "write 1 word"]: no offsets
        run_table(plc, [0x0106, 0x0000, 0x0106, 5, 77], 12)
        run_table(plc, [0x0106, 0x0300, 0x0104, 5, 1], 12)  # FC04 reads the same words
        assert not plc["%MSG3.E"] and u(plc, 7) == 77
        plc.close()


def test_exception_reply_lands_in_the_table():
    # an illegal address: the reply is the exception frame (FC | 16#80, code 2); the
    # exchange itself succeeded [our reading: the manual's master reports the frame]
    with PymodbusServer() as srv:
        plc = PLC.from_source(ONE_SHOT.format(n=10), config(srv.port))
        run_table(plc, [0x0106, 0x0000, 0x0103, 900, 2], 10)
        assert plc["%MSG3.D"] and not plc["%MSG3.E"]
        assert u(plc, 5) == 0x0183 and u(plc, 6) >> 8 == 2
        plc.close()


def test_timeout_counts_in_virtual_time(silent_port):
    # a server that accepts and never answers: %SW65 = 5 [manual] once the configured
    # timeout has passed in PLC time, not earlier, whatever the machine's speed
    plc = PLC.from_source(ONE_SHOT.format(n=10), config(silent_port, timeout="100ms"))
    run_table(plc, READ_WORD_0, 10, scans=0)
    _, seconds = finish(plc)
    assert plc["%MSG3.E"] and plc["%SW65"] == exch.ERR_TIMEOUT
    assert seconds == pytest.approx(0.100, abs=0.011)
    plc.close()


def test_nothing_listening():
    with refused_port() as port:
        plc = PLC.from_source(ONE_SHOT.format(n=10), config(port))
        run_table(plc, READ_WORD_0, 10)
    assert plc["%MSG3.D"] and plc["%MSG3.E"] and plc["%SW65"] == exch.ERR_TX
    assert plc.state == "RUN"


@pytest.mark.parametrize("words, n, code", [
    ([0x0506, 0x0300, 0x0103, 0, 1], 10, exch.ERR_COMMAND),  # command 5
    ([0x0120, 0x0000, 0x0103, 0, 1], 10, exch.ERR_TX_TABLE),  # 32 bytes in 10 words
    ([0x01FF, 0x0000, 0x0103, 0, 1], 200, exch.ERR_TX_TOO_LONG),  # 255 > 250 bytes
    ([0x0106, 0x0009, 0x0103, 0, 1], 10, exch.ERR_TX_OFFSET),  # offset 9 > 6 bytes
    ([0x0106, 0x0300, 0x0903, 0, 1], 10, exch.ERR_DEVICE),  # remote device 9: none
    ([0x0106, 0x0300, 0x0103, 0, 9], 10, exch.ERR_RX_OVERFLOW),  # 9 words do not fit
    ([0x0106, 0x0F00, 0x0103, 0, 1], 6, exch.ERR_RX_OFFSET),  # offset 15, 2 bytes of room
    ([0x0106, 0x0300], 2, exch.ERR_TABLE),  # no room for a request
])
def test_malformed_table_is_a_status_code_not_a_crash(words, n, code):
    # [manual: %SW63 codes 1 too many bytes, 2 transmission table too small, 4 reception
    # table overflow, 7 bad command, 11 transmission offset; 8 our choice for a device]
    with PymodbusServer() as srv:
        plc = PLC.from_source(ONE_SHOT.format(n=n), config(srv.port))
        run_table(plc, words, n)
        assert plc["%MSG3.D"] and plc["%MSG3.E"] and plc["%SW65"] == code
        assert plc.state == "RUN"
        plc.close()


def test_malformed_reply():
    # a peer that answers with a bad MBAP header (protocol 5): reception error 9
    # [manual: %SW63 code 9]
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen()

        def answer() -> None:
            conn, _ = srv.accept()
            with conn:
                conn.recv(64)
                conn.sendall(bytes([0, 1, 0, 5, 0, 2, 1, 3]))

        t = threading.Thread(target=answer, daemon=True)
        t.start()
        plc = PLC.from_source(ONE_SHOT.format(n=10), config(srv.getsockname()[1]))
        run_table(plc, READ_WORD_0, 10)
        assert plc["%MSG3.E"] and plc["%SW65"] == exch.ERR_RX
        t.join(5)
        plc.close()


def test_one_exchange_at_a_time_and_reset(silent_port):
    # an EXCH while one is in progress is ignored [manual: test %MSG.D first]; R drops
    # the exchange in progress: D = 1, E = 0 [manual]
    src = "LD %M0\nEXCH3 %MW0:10\nLD %M1\nEXCH3 %MW20:10\nBLK %MSG3\nLD %M2\nR\nEND_BLK\n"
    plc = PLC.from_source(src, config(silent_port, timeout="200ms"))
    for base, idx in ((0, 1), (20, 9)):  # the second names no device: would fail at once
        for k, v in enumerate([0x0106, 0x0300, idx << 8 | 3, 0, 1]):
            plc.mem.mw.w[base + k] = v
    plc["%M0"] = 1
    plc.scan()
    plc["%M0"], plc["%M1"] = 0, 1
    plc.scan(3)
    assert not plc["%MSG3.D"] and plc["%SW65"] == 0  # still the first, no error 8
    plc["%M1"], plc["%M2"] = 0, 1
    plc.scan()
    assert plc["%MSG3.D"] and not plc["%MSG3.E"]
    plc.close()


def test_stop_ends_the_exchange(silent_port):
    plc = PLC.from_source(ONE_SHOT.format(n=10), config(silent_port))
    run_table(plc, READ_WORD_0, 10, scans=0)
    plc.stop()
    plc.scan()
    assert plc["%MSG3.D"] and plc["%MSG3.E"] and plc["%SW65"] == exch.ERR_STOPPED
    plc.close()


@pytest.mark.parametrize("src, cfg, message", [
    ("LD 1\nEXCH3 %MW0:10\n", {}, "not configured"),
    ("LD 1\nEXCH1 %MW0:10\n", None, "serial port 1 is not emulated"),
    ("LD 1\nEXCH4 %MW0:10\n", None, "no such port"),
    ("LD 1\nEXCH3 %MD0\n", None, "not a word table"),
    ("LD %MSG0.D\nST %Q0.0\n", None, "%MSG1"),
    ("LD 1\nST %MSG3.D\n", None, "MSG3.D"),  # a block output cannot be written
])
def test_check_rejects_misuse(src, cfg, message):
    with pytest.raises((ProgramError, ConfigError)) as e:
        PLC.from_source(src, config(502) if cfg is None else cfg)
    assert message in str(e.value)


@pytest.mark.parametrize("section, message", [
    ({"remote": {"17": {"host": "h"}}}, "exch.remote.17"),
    ({"remote": {"1": {"host": "h", "port": 0}}}, "exch.remote.1.port"),
    ({"timeout": "0s", "remote": {"1": {"host": "h"}}}, "exch.timeout"),
    ({"timeout": "2min", "remote": {"1": {"host": "h"}}},
     "exch.timeout: must be from 0.01 s to 60 s (got '2min')"),
    ({"remote": {"1": {"host": "h" * 254}}}, "exch.remote.1.host"),
    ({"remote": {"1": {"host": "h", "unit_id": 256}}}, "exch.remote.1.unit_id"),
    ({"remote": {}}, "no remote device"),
    ({"remote": {"1": {"host": "h", "unit": 1}}}, "exch.remote.1.unit"),
])
def test_bad_configuration(section, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nEXCH3 %MW0:10\n", {"exch": section})
    assert message in str(e.value)


def test_exch_prints_back_as_written():
    prog = parse("LD %MSG3.D\nEXCH3 %MW0:10\n")
    assert "EXCH3 %MW0:10" in format_program(prog)


REMOTE_STATION = """
(* the remote I/O station: input word 0 bit 0 set, word 1 = 4321 *)
LD 1
[%MW0 := 1]
[%MW1 := 4321]
"""


def test_remote_io_example_polls_a_second_softplc_daemon(tmp_path, daemons):
    station = started(daemons, tmp_path, program=REMOTE_STATION)
    cfg = tomllib.loads((EXAMPLES / "remote_io.toml").read_text())
    cfg["exch"]["remote"]["1"]["port"] = station.port
    plc = PLC.from_file(EXAMPLES / "remote_io.il", cfg)
    plc.force("%I0.0", 1)
    plc.scan(20)
    assert not plc["%Q0.0"] and plc["%SW65"] == 0
    assert [plc["%MW20"], plc["%MW21"]] == [1, 4321]  # the station's input words, read
    reads = plc["%MW22"]
    assert reads >= 9  # one exchange a scan, alternating read / write
    with station.client() as c:
        pdu = c.request(bytes([3, 0, 10, 0, 1]))  # the station's output word, register 10
    out = pdu[2] << 8 | pdu[3]
    assert out & 1 == 1  # its input bit 0 AND the local enable %I0.0
    assert out >> 8 in ((reads - 1) & 127, reads & 127)  # the read count: we poll it
    plc.force("%I0.0", 0)
    plc.scan(4)
    with station.client() as c:
        pdu = c.request(bytes([3, 0, 10, 0, 1]))
    assert pdu[3] & 1 == 0
    plc.close()


def test_real_clock_never_blocks_the_scan(silent_port):
    # on the real clock the scan only looks whether the reply arrived: scans go on while
    # the silent server keeps the exchange pending, and the timeout ends it
    plc = PLC.from_source(ONE_SHOT.format(n=10),
                          config(silent_port, timeout="100ms"), clock="real")
    run_table(plc, READ_WORD_0, 10, scans=0)
    scans, _ = finish(plc)
    assert scans > 3  # 10 ms scans during a 100 ms wait
    assert plc["%SW65"] == exch.ERR_TIMEOUT
    plc.close()
    with PymodbusServer() as srv:  # and a reply lands at a later scan boundary
        plc = PLC.from_source(ONE_SHOT.format(n=10), config(srv.port), clock="real")
        run_table(plc, [0x0106, 0x0300, 0x0103, 4, 1], 10, scans=0)
        finish(plc)
        assert not plc["%MSG3.E"] and u(plc, 7) == 104
        plc.close()


def test_repl_prints_the_block(tmp_path):
    from softplc.debug.session import Session

    prog = tmp_path / "p.il"
    prog.write_text(ONE_SHOT.format(n=10))
    with refused_port() as port:
        plc = PLC.from_file(prog, config(port))
        s = Session(plc, prog)
        assert s.execute("print %MSG3") == "%MSG3 = D=1 E=0"
        run_table(plc, READ_WORD_0, 10)  # nothing listening: error 6
    assert s.execute("print %MSG3.E %SW65") == "%MSG3.E = 1\n%SW65 = 6"
    plc.close()


def test_ladder_view_shows_the_exchange(capsys):
    from softplc.cli import main

    assert main(["ladder", str(EXAMPLES / "remote_io.il"),
                 "--config", str(EXAMPLES / "remote_io.toml")]) == 0
    out = capsys.readouterr().out
    assert "EXCH3 %MW0:9" in out and "EXCH3 %MW10:10" in out


def test_bits_against_a_second_plc():
    # FC05 write one bit, FC15 write 10 bits, FC01 read them [manual: the master's bit
    # tables are the same layout: command | length, offsets, index | FC, address, ...];
    # the second PLC serves %M as coils (softplc's own server, in this process)
    from softplc.modbus import ServerThread
    from softplc.modbus.image import ModbusImage

    station = PLC.from_source("LD %M3\nST %Q0.0\n")
    image = ModbusImage(station.mem)
    server = ServerThread(image, "127.0.0.1", 0).start()
    try:
        plc = PLC.from_source(ONE_SHOT.format(n=12), config(server.port))

        def station_scan() -> None:
            image.apply_writes()
            station.scan()
            image.take_snapshot()

        # FC05: bit 3 := 1 (16#FF00), no offsets; the reply echoes the request
        run_table(plc, [0x0106, 0x0000, 0x0105, 3, 0xFF00], 12)
        assert not plc["%MSG3.E"] and [u(plc, 5), u(plc, 6), u(plc, 7)] == [0x0105, 3, 0xFF00]
        station_scan()
        assert station["%M3"] and station["%Q0.0"]
        # FC15: bits 8..17 := 10 bits 2#10_1100_0101; Tx 8 + 2 data bytes = 10, Tx offset 7
        run_table(plc, [0x010A, 0x0007, 0x010F, 8, 10, 0x0002, 0xC502], 12)
        assert not plc["%MSG3.E"] and [u(plc, 7), u(plc, 8), u(plc, 9)] == [0x010F, 8, 10]
        station_scan()
        assert [station[f"%M{8 + k}"] for k in range(10)] == [1, 0, 1, 0, 0, 0, 1, 1, 0, 1]
        # FC01: read 16 bits from 0, Rx offset 3: 16#0101, 16#0002, then the two bytes
        run_table(plc, [0x0106, 0x0300, 0x0101, 0, 16], 12)
        assert not plc["%MSG3.E"] and [u(plc, 5), u(plc, 6), u(plc, 7)] == \
            [0x0101, 0x0002, 0x08C5]  # bits 0-7: %M3; bits 8-15 as written
        plc.close()
    finally:
        server.stop()


def test_softplc_check(tmp_path, capsys):
    from softplc.cli import main

    assert main(["check", str(EXAMPLES / "remote_io.il"),
                 "--config", str(EXAMPLES / "remote_io.toml")]) == 0
    bad = tmp_path / "bad.il"
    bad.write_text("LD 1\nEXCH3 %MW0:10\nEXCH2 %MW20:4\nLD %MSG3.Q\nST %Q0.0\n")
    assert main(["check", str(bad)]) == 1
    out = capsys.readouterr()
    text = out.out + out.err
    assert "bad.il:2:1: EXCH3 is used but the port is not configured" in text
    assert "bad.il:3:1: EXCH2: the serial port 2 is not emulated" in text
    assert "%MSG has fields .D, .E" in text


# -- issue 21: one deadline per exchange, never blocking the scan or a signal ---------------
@pytest.fixture
def dripper():
    """A remote that reads a request, then answers one byte every 50 ms, for ever (an
    MBAP header announcing 254 bytes, then zeros): each recv() sees a byte in time."""
    with Dripper(0.05) as d:
        yield d


def test_dripping_remote_fails_at_the_deadline_in_virtual_time(dripper):
    # a byte every 50 ms stays under any per-recv timeout: the exchange's one deadline
    # (300 ms after the request) ends it, delivered at that PLC time, and scans go on
    plc = PLC.from_source(ONE_SHOT.format(n=10) + "LD 1\n[%MW30 := %MW30 + 1]\n",
                          config(dripper.port, timeout="300ms"))
    run_table(plc, READ_WORD_0, 10, scans=0)
    _, seconds = finish(plc)
    assert plc["%MSG3.E"] and plc["%SW65"] == exch.ERR_TIMEOUT
    assert seconds == pytest.approx(0.300, abs=0.011)
    before = plc["%MW30"]
    plc.scan(50)
    assert plc["%MW30"] == before + 50
    plc.close()


def test_dripping_remote_does_not_hold_the_next_exchange(dripper):
    # real clock: the scans run while the drip goes on; the exchange fails at its
    # deadline; the next one, to a healthy remote, is not queued behind the dripping one
    with PymodbusServer() as srv:
        cfg = config(dripper.port, timeout="300ms")
        cfg["exch"]["remote"]["2"] = {"host": "127.0.0.1", "port": srv.port, "unit_id": 1}
        plc = PLC.from_source(ONE_SHOT.format(n=10), cfg, clock="real")
        run_table(plc, READ_WORD_0, 10, scans=0)
        scans, _ = finish(plc)
        assert plc["%SW65"] == exch.ERR_TIMEOUT and scans > 3
        run_table(plc, [0x0106, 0x0300, 0x0203, 4, 1], 10, scans=0)
        finish(plc)
        assert not plc["%MSG3.E"] and u(plc, 7) == 104
        plc.close()


@pytest.mark.parametrize("speed", [None, "max"])
def test_daemon_stops_within_a_second_during_a_drip(tmp_path, daemons, dripper, speed):
    cfg = tmp_path / "m.toml"
    cfg.write_text(dripper.config("60s"))
    args = ["--config", str(cfg), "--rt-priority", "0"]
    d = started(daemons, tmp_path, *args, *(["--speed", speed] if speed else []),
                program=bench_exch.PROGRAM)
    assert dripper.requests.wait(10)  # the exchange is out, the remote drips
    time.sleep(0.5)
    t0 = time.monotonic()
    d.proc.send_signal(signal.SIGTERM)
    assert "outputs 0" in d.wait_for("stopped after")
    # stopped within 1 s (was: up to 5 s in the --speed max scan's wait for the worker)
    assert time.monotonic() - t0 < 1.0
    # and the process is gone (was: never, while the remote dripped: the exit waited for
    # the worker thread); 5 s leaves room for a loaded machine, 0.1-0.3 s is usual
    assert d.proc.wait(5) == 0
