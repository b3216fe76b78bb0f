"""The Modbus TCP codec every side shares: the MBAP header (server, raw client, the EXCH
instruction's client) and the 32-bit values carried in two registers (the hosts, the
register maps, the servo table's words).

It imports nothing of softplc and stands outside the `softplc.modbus` package, so the
runtime (EXCH) may use it although that package sits above the runtime (a low layer of its
own in tools/check_structure.py; no package cycle: docs/decisions/one-modbus-codec.md).

MBAP header [Modbus Messaging on TCP/IP Implementation Guide v1.0b, 3.1.3]: transaction
id, protocol id (0 = Modbus), length (the bytes that follow: unit id + PDU), unit id; big
endian, 7 bytes. A PDU is at most 253 bytes [Modbus Application Protocol v1.1b3, 4.1].

Word pairs: a Twido %MD / %MF is two consecutive %MW, the low word first
[manual, from memory: TwidoSoft, "Double words and floating point objects"], served as two
holding registers in that order ("CDAB" to a host that names byte orders).
"""

from __future__ import annotations

import struct

MBAP = struct.Struct(">HHHB")  # transaction id, protocol id, length, unit id
MBAP_SIZE = MBAP.size  # 7
PROTOCOL_MODBUS = 0
MAX_PDU = 253  # bytes [MB application protocol v1.1b3, 4.1]
MIN_LENGTH = 2  # the length field: unit id + at least a function code
MAX_LENGTH = MAX_PDU + 1  # unit id + the longest PDU
# the length fields of a well-formed frame (a set: the server tests each request inline)
GOOD_LENGTHS = frozenset(range(MIN_LENGTH, MAX_LENGTH + 1))

# (bound methods: the server parses every request with them)
header = MBAP.unpack_from  # header(buf, pos=0) -> (tid, protocol, length, unit)
_pack = MBAP.pack


def frame(tid: int, unit: int, pdu: bytes) -> bytes:
    """An MBAP frame: the header for `pdu`, then `pdu`."""
    return _pack(tid, PROTOCOL_MODBUS, len(pdu) + 1, unit) + pdu


def bad_header(protocol: int, length: int) -> str | None:
    """Why a header is not a Modbus one (protocol id, length out of range), or None."""
    if protocol != PROTOCOL_MODBUS or length not in GOOD_LENGTHS:
        return f"bad MBAP header (protocol id {protocol}, length {length})"
    return None


# -- 32-bit values in two 16-bit registers (low word first, unsigned on the wire) ----------
_WORDS = struct.Struct("<HH")
_REAL = struct.Struct("<f")
_DINT = struct.Struct("<i")
DINT_MIN, DINT_MAX = -(2 ** 31), 2 ** 31 - 1


def float_to_words(value: float) -> tuple[int, int]:
    """A %MF (IEEE single) as (low, high) registers. OverflowError beyond +-3.4e38."""
    return _WORDS.unpack(_REAL.pack(value))  # type: ignore[return-value]


def words_to_float(low: int, high: int) -> float:
    return _REAL.unpack(_WORDS.pack(low & 0xFFFF, high & 0xFFFF))[0]


def long_to_words(value: int) -> tuple[int, int]:
    """A %MD (32-bit signed) as (low, high) registers; ValueError if it does not fit."""
    if not DINT_MIN <= value <= DINT_MAX:
        raise ValueError(f"{value} does not fit a %MD (32-bit) word")
    u = value & 0xFFFFFFFF
    return u & 0xFFFF, u >> 16


def words_to_long(low: int, high: int) -> int:
    return _DINT.unpack(_WORDS.pack(low & 0xFFFF, high & 0xFFFF))[0]


def signed_word(u: int) -> int:
    """A holding register (unsigned on the wire) as the PLC's signed %MW."""
    u &= 0xFFFF
    return u - 0x10000 if u & 0x8000 else u
