"""The Twido Modbus TCP register map: the one table of what a host can reach and how.

Everything the server knows about the Modbus side of a Twido lives here: which function
codes exist, which PLC objects they reach, the per-request quantity limits, the exception
codes, the device identification strings and the configurable read-only ranges. The
protocol code (`protocol.py`) only follows this table.

Address n of the register space is %MWn, address n of the coil space is %Mn [manual,
TWD USE 10AE]; FC 4 and FC 2 read the same objects as FC 3 and FC 1. %MDi / %MFi are the
two registers i (low word) and i+1 (high word) [sure].
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import IntEnum

from softplc.twido.address import WIDTH, Ref, parse_address
from softplc.twido.profile import DEFAULT_PROFILE, Profile


class ExceptionCode(IntEnum):
    """Modbus exception codes the server answers with."""

    ILLEGAL_FUNCTION = 0x01  # function code not supported
    ILLEGAL_DATA_ADDRESS = 0x02  # outside the image, or a write into a read-only range
    ILLEGAL_DATA_VALUE = 0x03  # bad quantity, byte count, coil value or PDU length
    SERVER_DEVICE_FAILURE = 0x04  # unexpected internal error (never expected)


COILS, REGISTERS, DEVICE_ID = "coils", "registers", "device-id"


@dataclass(frozen=True)
class Function:
    """One supported function code."""

    code: int
    name: str
    space: str  # COILS, REGISTERS or DEVICE_ID
    access: str  # "read", "write" or "read/write"
    max_quantity: int  # per-request limit (Modbus Application Protocol v1.1b3)
    objects: str  # what it reaches, for humans


# The map. Limits: read 125 registers / 2000 coils, write 123 registers / 1968 coils;
# FC 23 writes at most 121 registers (its frame has 4 more header bytes).
FUNCTIONS: dict[int, Function] = {f.code: f for f in (
    Function(1, "Read Coils", COILS, "read", 2000, "%Mn"),
    Function(2, "Read Discrete Inputs", COILS, "read", 2000, "%Mn (same bits as FC 1)"),
    Function(3, "Read Holding Registers", REGISTERS, "read", 125, "%MWn"),
    Function(4, "Read Input Registers", REGISTERS, "read", 125, "%MWn (same words as FC 3)"),
    Function(5, "Write Single Coil", COILS, "write", 1, "%Mn"),
    Function(6, "Write Single Register", REGISTERS, "write", 1, "%MWn"),
    Function(15, "Write Multiple Coils", COILS, "write", 1968, "%Mn"),
    Function(16, "Write Multiple Registers", REGISTERS, "write", 123, "%MWn"),
    Function(23, "Read/Write Multiple Registers", REGISTERS, "read/write", 125,
             "%MWn (write at most 121)"),
    Function(43, "Read Device Identification (MEI 14)", DEVICE_ID, "read", 0,
             "vendor, product code, revision"),
)}
FC23_MAX_WRITE = 121
MEI_READ_DEVICE_ID = 0x0E

# What a real TWDLCAE40DRF, firmware 05.40, answers to FC 43 / MEI 14 [sure]. Object ids
# 0, 1, 2 are the "basic" category: VendorName, ProductCode, MajorMinorRevision.
DEVICE_IDENTIFICATION: dict[int, bytes] = {
    0x00: b"TELEMECANIQUE",
    0x01: b"TWDLCAE40DRF",
    0x02: b"05.40",
}
# Conformity level 0x81: basic identification, stream and individual access. Not captured
# from a real Twido: chosen as the level that matches the objects above.
DEVICE_ID_CONFORMITY = 0x81

# Any unit id is accepted and echoed, as a real TWDLCAE40DRF does on 0, 1 and 255 [sure].
ACCEPT_ANY_UNIT_ID = True
DEFAULT_PORT = 5020  # a real Twido listens on 502; 5020 needs no privileges


@dataclass(frozen=True)
class ReadOnly:
    """Address ranges (half-open [start, stop)) where Modbus writes get exception 02."""

    registers: tuple[tuple[int, int], ...] = ()
    coils: tuple[tuple[int, int], ...] = ()

    def blocks(self, space: str, start: int, count: int) -> bool:
        """True if a write of `count` items at `start` touches a read-only range."""
        stop = start + count
        for a, b in self.registers if space == REGISTERS else self.coils:  # hot: no genexpr
            if start < b and a < stop:
                return True
        return False


def span(ref: Ref) -> tuple[str, int, int] | None:
    """(table, first item, item count) of a %M/%MW/%MD/%MF object on the map; None for an
    object no host reaches. %MD/%MF take two registers each."""
    if ref.kind == "M":
        return COILS, ref.index, ref.length or 1
    if ref.kind in ("MW", "MD", "MF"):
        return REGISTERS, ref.index, (ref.length or 1) * WIDTH[ref.kind]
    return None


def read_only_range(text: str, profile: Profile = DEFAULT_PROFILE) -> tuple[str, int, int]:
    """(table, first item, item count) of one `[modbus] read_only` entry: %MWi, %MDi, %MFi
    (two registers), tables %MWi:L, %MDi:L, %MFi:L, bits %Mi and bit strings %Mi:L.
    ValueError (AddressError for a malformed address) saying what is wrong; the
    configuration schema checks each entry with it (`softplc.config.ModbusConfig`)."""
    ref = parse_address(text, profile)
    if ref.bit is not None or ref.offset is not None or ref.field is not None:
        raise ValueError("not a word or bit range (%MWi, %MWi:L, %Mi:L...)")
    where = span(ref)
    if where is None:
        raise ValueError("only %M, %MW, %MD, %MF objects are reachable over Modbus")
    return where


def read_only_of(entries: Iterable[str] | str, profile: Profile = DEFAULT_PROFILE) -> ReadOnly:
    """The ranges of `[modbus] read_only = ["%MW100:20", "%M0:8", "%MF40", ...]`, entries
    as the configuration schema checked them (`plc.settings.modbus.read_only`)."""
    regs: list[tuple[int, int]] = []
    coils: list[tuple[int, int]] = []
    for text in [entries] if isinstance(entries, str) else entries:
        space, start, count = read_only_range(text, profile)
        (coils if space == COILS else regs).append((start, start + count))
    return ReadOnly(tuple(regs), tuple(coils))


def describe(n_registers: int, n_coils: int, read_only: ReadOnly | None = None) -> list[str]:
    """The register map as text lines, for the start-up banner."""
    read_only = read_only or ReadOnly()
    lines = [
        f"registers 0..{n_registers - 1} = %MW0..%MW{n_registers - 1} "
        f"(FC 3/4 read, FC 6/16/23 write; %MD/%MF i = registers i, i+1, low word first)",
        f"coils     0..{n_coils - 1} = %M0..%M{n_coils - 1} (FC 1/2 read, FC 5/15 write)",
        "FC 43/14 device id: " + ", ".join(v.decode() for v in DEVICE_IDENTIFICATION.values())
        + "; any unit id",
    ]
    for name, ranges, prefix in (("registers", read_only.registers, "%MW"),
                                 ("coils", read_only.coils, "%M")):
        if ranges:
            lines.append(f"read-only {name}: " + ", ".join(
                f"{prefix}{a}..{prefix}{b - 1}" for a, b in ranges))
    return lines


def markdown_table() -> str:
    """The function-code table as markdown (the docs' generated Modbus map, `--help`)."""
    rows = ["| FC | function | objects | max quantity |", "|---|---|---|---|"]
    for f in FUNCTIONS.values():
        q = str(f.max_quantity) if f.max_quantity else "-"
        rows.append(f"| {f.code} | {f.name} | {f.objects} | {q} |")
    return "\n".join(rows)
