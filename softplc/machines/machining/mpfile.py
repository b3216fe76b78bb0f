"""The binary NC parameter macro (MPSetTemp.H / MPSet.H) of mass-estimation.md §3.4.

Heidenhain's binary NC format is not encrypted: numbers are IEEE-754 binary64 little-endian
(the thesis's "swap digit pairs" is a byte reversal). Layout, byte-exact on the thesis's
400-byte dump (Fig. 3-42):

    16-byte header (not decoded)
    blocks: u16 L | L bytes | u16 L          (little-endian; the trailer repeats L)

A Q assignment block is ``13 00 01 03 | Q u16 | 49 1F 00 02 48 00 04 06 | float64 | comment``;
a comment element (every ``;`` of the listing) is ``15 NN 08 03`` + ASCII + NUL, padded to an
even length, NN = element length in 16-bit words. Other blocks (BEGIN/END PGM, FN 17 lines:
their encodings are unknown) are kept as opaque bytes. Values are patched by Q number, in
place: only the 8 value bytes change, the file keeps its length.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from softplc.errors import MassFileError
from softplc.machines.machining.files import read_bytes

HEADER = bytes.fromhex("10000000 0000E803 01000000 00000000".replace(" ", ""))
Q_PREFIX = bytes.fromhex("13000103")
Q_MIDDLE = bytes.fromhex("491F000248000406")
COMMENT_MARK = bytes.fromhex("0803")  # after the tag byte 0x15 and the length byte
COMMENT_TAG = 0x15
_U16 = struct.Struct("<H")
_F64 = struct.Struct("<d")
# offset of the float64 inside a Q block body: prefix, Q number, middle
_VALUE_AT = len(Q_PREFIX) + 2 + len(Q_MIDDLE)


def encode_double(x: float) -> bytes:
    """The 8 bytes the NC file stores for `x` (IEEE-754 binary64, little-endian)."""
    return _F64.pack(x)


def decode_double(b: bytes) -> float:
    return _F64.unpack(b)[0]


def comment_element(text: str) -> bytes:
    """One comment element: ``15 NN 08 03`` + ASCII + NUL, padded to an even length."""
    body = text.encode("ascii") + b"\0"
    if (4 + len(body)) % 2:
        body += b"\0"
    words = (4 + len(body)) // 2
    if words > 0xFF:
        raise MassFileError(f"comment {text!r} too long for one element")
    return bytes([COMMENT_TAG, words]) + COMMENT_MARK + body


def q_block_body(q: int, value: float, comment: str) -> bytes:
    return Q_PREFIX + _U16.pack(q) + Q_MIDDLE + encode_double(value) + comment_element(comment)


@dataclass(frozen=True)
class Block:
    """One block of the file: where its body starts and, for a Q assignment, which Q."""

    offset: int  # file offset of the length word
    body: bytes
    q: int | None = None  # Q number of a Q assignment block

    @property
    def value_offset(self) -> int:
        """File offset of the float64 of a Q assignment."""
        return self.offset + 2 + _VALUE_AT

    @property
    def value(self) -> float:
        return decode_double(self.body[_VALUE_AT:_VALUE_AT + 8])


class MPFile:
    """A parsed parameter macro. `bytes(mp)` re-emits the input byte for byte.

    `complete=False` accepts a file that ends inside a block (the thesis's dump stops in the
    middle of Q2's block); such a tail is kept as is.
    """

    def __init__(self, data: bytes, *, name: str = "<bytes>", complete: bool = True):
        self.name = name
        self.data = bytes(data)
        self.blocks: list[Block] = []
        self.tail = b""
        if self.data[:len(HEADER)] != HEADER[:len(self.data)] or len(self.data) < len(HEADER):
            raise MassFileError(f"{name}: not a binary NC file (header "
                                f"{self.data[:16].hex(' ')!r}, expected {HEADER.hex(' ')})")
        pos = len(HEADER)
        while pos < len(self.data):
            if pos + 2 > len(self.data):
                self._truncated(pos, complete)
                break
            (n,) = _U16.unpack_from(self.data, pos)
            end = pos + 2 + n
            if end + 2 > len(self.data):
                self._truncated(pos, complete)
                break
            (trailer,) = _U16.unpack_from(self.data, end)
            if trailer != n:
                raise MassFileError(f"{name}: offset 0x{end:X}: block trailer {trailer} "
                                    f"differs from its length word {n} (at 0x{pos:X})")
            body = self.data[pos + 2:end]
            q = None
            if body[:4] == Q_PREFIX and body[6:6 + len(Q_MIDDLE)] == Q_MIDDLE \
                    and len(body) >= _VALUE_AT + 8:
                (q,) = _U16.unpack_from(body, 4)
            self.blocks.append(Block(pos, body, q))
            pos = end + 2

    def _truncated(self, pos: int, complete: bool) -> None:
        if complete:
            raise MassFileError(f"{self.name}: offset 0x{pos:X}: file ends inside a block")
        self.tail = self.data[pos:]

    @classmethod
    def read(cls, path: str | Path) -> MPFile:
        return cls(read_bytes(path, "parameter file"), name=str(path))

    def __bytes__(self) -> bytes:
        out = bytearray(HEADER)
        for b in self.blocks:
            out += _U16.pack(len(b.body)) + b.body + _U16.pack(len(b.body))
        return bytes(out + self.tail)

    def q_blocks(self) -> dict[int, Block]:
        return {b.q: b for b in self.blocks if b.q is not None}

    def values(self) -> dict[int, float]:
        """Q number -> value of every Q assignment."""
        return {q: b.value for q, b in self.q_blocks().items()}

    def patched(self, values: Mapping[int, float]) -> bytes:
        """The file with the given Q values replaced; only their 8 value bytes change."""
        blocks = self.q_blocks()
        missing = sorted(set(values) - set(blocks))
        if missing:
            raise MassFileError(f"{self.name}: no assignment of "
                                f"{', '.join(f'Q{q}' for q in missing)} in the template")
        out = bytearray(self.data)
        for q, v in values.items():
            at = blocks[q].value_offset
            out[at:at + 8] = encode_double(float(v))
        return bytes(out)


def build(blocks: list[tuple[str, object]]) -> bytes:
    """A parameter macro from ("comment", text) and ("q", (number, value, comment)) items.

    Reproduces the known layout (Fig. 3-42); encodings of other NC lines are not known, so
    none are emitted.
    """
    out = bytearray(HEADER)

    def block(body: bytes) -> None:
        out.extend(_U16.pack(len(body)) + body + _U16.pack(len(body)))

    block(b"\0\0")  # the first block of the thesis's dump (2 bytes, meaning unknown)
    for kind, item in blocks:
        if kind == "comment":
            block(comment_element(str(item)))
        else:
            q, value, text = item  # type: ignore[misc]
            block(q_block_body(q, value, text))
    return bytes(out)
