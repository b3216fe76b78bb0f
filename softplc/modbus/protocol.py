"""Modbus PDU handling: request PDU in, response PDU out, following `regmap`.

Checks follow the order of the Modbus Application Protocol (v1.1b3, figures 9-21):
function code (01), then quantity and PDU length (03), then address range and read-only
ranges (02). Every request gets an answer: a normal response or an exception response.

`--read-only` (`ModbusImage.writes_allowed` False) answers every writing function (5, 6,
15, 16 and 23, whose read part goes unanswered too) with 01, ILLEGAL FUNCTION: the spec
gives 01 for a function "not an allowable action for the server", including "the server
is in the wrong state to process a request of this type"; 02 stays what it is elsewhere,
an address (range) that cannot be written while others can.
"""

from __future__ import annotations

from collections.abc import Callable
from struct import pack, unpack_from

import numpy as np

from softplc.modbus.image import ModbusImage
from softplc.modbus.regmap import (
    COILS,
    DEVICE_ID_CONFORMITY,
    DEVICE_IDENTIFICATION,
    FC23_MAX_WRITE,
    FUNCTIONS,
    MEI_READ_DEVICE_ID,
    REGISTERS,
    ExceptionCode,
)

ILLEGAL_FUNCTION = ExceptionCode.ILLEGAL_FUNCTION
ILLEGAL_ADDRESS = ExceptionCode.ILLEGAL_DATA_ADDRESS
ILLEGAL_VALUE = ExceptionCode.ILLEGAL_DATA_VALUE


def exception(fc: int, code: int) -> bytes:
    return bytes(((fc | 0x80) & 0xFF, code))


_READS = {fc: (f.max_quantity, f.space == REGISTERS) for fc, f in FUNCTIONS.items()
          if fc in (1, 2, 3, 4)}  # fc -> (max quantity, registers?): the hot path's lookup


def _read(img: ModbusImage, pdu: bytes) -> bytes:
    fc = pdu[0]
    if len(pdu) != 5:
        return exception(fc, ILLEGAL_VALUE)
    addr, qty = unpack_from(">HH", pdu, 1)
    max_qty, registers = _READS[fc]
    if not 1 <= qty <= max_qty:
        return exception(fc, ILLEGAL_VALUE)
    if registers:
        if addr + qty > img.n_registers:
            return exception(fc, ILLEGAL_ADDRESS)
        return pack("BB", fc, 2 * qty) + img.regs_wire[2 * addr:2 * (addr + qty)]
    if addr + qty > img.n_coils:
        return exception(fc, ILLEGAL_ADDRESS)
    data = img.read_coils_packed(addr, qty)
    return bytes((fc, len(data))) + data


def _write_single_coil(img: ModbusImage, pdu: bytes) -> bytes:
    if len(pdu) != 5:
        return exception(5, ILLEGAL_VALUE)
    addr, value = unpack_from(">HH", pdu, 1)
    if value not in (0xFF00, 0x0000):
        return exception(5, ILLEGAL_VALUE)
    if addr >= img.n_coils or img.read_only.blocks(COILS, addr, 1):
        return exception(5, ILLEGAL_ADDRESS)
    img.queue_coils(addr, b"\x01" if value else b"\x00")
    return bytes(pdu)  # the echo is what was written


def _write_single_register(img: ModbusImage, pdu: bytes) -> bytes:
    if len(pdu) != 5:
        return exception(6, ILLEGAL_VALUE)
    (addr,) = unpack_from(">H", pdu, 1)
    if addr >= img.n_registers or img.read_only.blocks(REGISTERS, addr, 1):
        return exception(6, ILLEGAL_ADDRESS)
    img.queue_registers(addr, pdu[3:5])
    return bytes(pdu)


def _write_multiple_coils(img: ModbusImage, pdu: bytes) -> bytes:
    if len(pdu) < 6:
        return exception(15, ILLEGAL_VALUE)
    addr, qty, nbytes = unpack_from(">HHB", pdu, 1)
    if not 1 <= qty <= FUNCTIONS[15].max_quantity or nbytes != (qty + 7) // 8 \
            or len(pdu) != 6 + nbytes:
        return exception(15, ILLEGAL_VALUE)
    if addr + qty > img.n_coils or img.read_only.blocks(COILS, addr, qty):
        return exception(15, ILLEGAL_ADDRESS)
    bits = np.unpackbits(np.frombuffer(pdu, np.uint8, nbytes, 6), count=qty, bitorder="little")
    img.queue_coils(addr, bits.tobytes())
    return pdu[:5]


def _write_multiple_registers(img: ModbusImage, pdu: bytes) -> bytes:
    if len(pdu) < 6:
        return exception(16, ILLEGAL_VALUE)
    addr, qty, nbytes = unpack_from(">HHB", pdu, 1)
    if not 1 <= qty <= FUNCTIONS[16].max_quantity or nbytes != 2 * qty \
            or len(pdu) != 6 + nbytes:
        return exception(16, ILLEGAL_VALUE)
    if addr + qty > img.n_registers or img.read_only.blocks(REGISTERS, addr, qty):
        return exception(16, ILLEGAL_ADDRESS)
    if img.value_checks and img.refusal(addr, pdu[6:]):  # a value a device refuses
        return exception(16, ILLEGAL_VALUE)
    img.queue_registers(addr, pdu[6:])
    return pdu[:5]


def _read_write_registers(img: ModbusImage, pdu: bytes) -> bytes:
    """FC 23. The write is queued like any other, so the read part returns the image of
    the last scan, without the write (which the next scan applies)."""
    if len(pdu) < 10:
        return exception(23, ILLEGAL_VALUE)
    raddr, rqty, waddr, wqty, nbytes = unpack_from(">HHHHB", pdu, 1)
    if not 1 <= rqty <= FUNCTIONS[23].max_quantity or not 1 <= wqty <= FC23_MAX_WRITE \
            or nbytes != 2 * wqty or len(pdu) != 10 + nbytes:
        return exception(23, ILLEGAL_VALUE)
    if raddr + rqty > img.n_registers or waddr + wqty > img.n_registers \
            or img.read_only.blocks(REGISTERS, waddr, wqty):
        return exception(23, ILLEGAL_ADDRESS)
    if img.value_checks and img.refusal(waddr, pdu[10:]):
        return exception(23, ILLEGAL_VALUE)
    data = img.read_registers_wire(raddr, rqty)
    img.queue_registers(waddr, pdu[10:])
    return bytes((23, 2 * rqty)) + data


def _device_identification(img: ModbusImage, pdu: bytes) -> bytes:
    """FC 43 / MEI 14. Codes 1-3 stream every object (all are basic), code 4 one object."""
    if len(pdu) < 2 or pdu[1] != MEI_READ_DEVICE_ID:
        return exception(43, ILLEGAL_FUNCTION)  # other MEI types (e.g. CANopen) unsupported
    if len(pdu) != 4 or not 1 <= pdu[2] <= 4:
        return exception(43, ILLEGAL_VALUE)
    code, obj = pdu[2], pdu[3]
    if code == 4:
        if obj not in DEVICE_IDENTIFICATION:
            return exception(43, ILLEGAL_ADDRESS)
        ids = [obj]
    else:
        # An unknown starting object restarts the stream at object 0 (MB spec 6.21).
        start = obj if obj in DEVICE_IDENTIFICATION else 0
        ids = [i for i in DEVICE_IDENTIFICATION if i >= start]
    out = bytearray((43, MEI_READ_DEVICE_ID, code, DEVICE_ID_CONFORMITY, 0, 0, len(ids)))
    for i in ids:
        v = DEVICE_IDENTIFICATION[i]
        out += bytes((i, len(v))) + v
    return bytes(out)


WRITE_FUNCTIONS = frozenset(f.code for f in FUNCTIONS.values() if "write" in f.access)

HANDLERS: dict[int, Callable[[ModbusImage, bytes], bytes]] = {
    1: _read, 2: _read, 3: _read, 4: _read,
    5: _write_single_coil, 6: _write_single_register,
    15: _write_multiple_coils, 16: _write_multiple_registers,
    23: _read_write_registers, 43: _device_identification,
}
assert set(HANDLERS) == set(FUNCTIONS), "regmap.FUNCTIONS and HANDLERS disagree"


def process_pdu(img: ModbusImage, pdu: bytes) -> bytes:
    """Answer one request PDU (function code + data) with a response PDU."""
    if not pdu:
        return exception(0, ILLEGAL_FUNCTION)
    handler = HANDLERS.get(pdu[0])
    if handler is None or not img.writes_allowed and pdu[0] in WRITE_FUNCTIONS:
        return exception(pdu[0], ILLEGAL_FUNCTION)
    return handler(img, pdu)

