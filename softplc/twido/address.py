"""Twido object addresses: the one parser for `%MW3`, `%I0.12`, `%MF40`, `%TM0.Q`...

The grammar, the PLC API, the Modbus tools and the debugger all turn address text into a
`Ref` here, so the address syntax lives in one place.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, replace
from dataclasses import field as dc_field  # Ref has a `field` of its own

from softplc.errors import AddressError
from softplc.twido import catalog
from softplc.twido.profile import DEFAULT_PROFILE, Profile

BOOL, INT16, INT32, REAL = "bool", "int16", "int32", "real"

# Plain indexed objects: kind -> value type.
SIMPLE_KINDS = {
    "M": BOOL, "S": BOOL, "X": BOOL,
    "MW": INT16, "KW": INT16, "SW": INT16,
    "MD": INT32, "KD": INT32,
    "MF": REAL, "KF": REAL,
}
IO_KINDS = {"I": BOOL, "Q": BOOL}
# Analog I/O words %IWm.c / %QWm.c (module m, channel c) [manual].
ANALOG_KINDS = {"IW": INT16, "QW": INT16}
ANALOG_STRIDE = 8  # word channels per module in the flat index (the widest analog module)
# Remote Link network words %INWi.j / %QNWi.j (issue 35): i the station (0 the master, 1-7
# the remotes), j = 0..3 [docs/twido.md#remote-link: FA164505, 4 words each way; the
# names, the indexes and the range 1-7: manual, from memory]. Flat index i * LINK_WORDS + j.
NETWORK_KINDS = {"INW": INT16, "QNW": INT16}
LINK_WORDS = 4  # words each way between the master and one peer [src S1]
LINK_STATIONS = 8  # address 0 (the master) and 1-7 (the remotes) [src S1, range from memory]
# Function-block objects: kind -> {field: (type, writable by the program)} (the catalog's).
BLOCK_FIELDS: dict[str, dict[str, tuple[str, bool]]] = {
    f.kind: dict(f.fields or {}) for f in catalog.addressable()}
# Objects the program may never write.
READ_ONLY_KINDS = {"I", "IW", "INW", "KW", "KD", "KF"}
# Word-backed kinds: the 16-bit family a 32-bit or float object overlays.
WORD_FAMILY = {"MW": "MW", "MD": "MW", "MF": "MW", "KW": "KW", "KD": "KW", "KF": "KW",
               "SW": "SW"}
# How many words an object occupies in its family.
WIDTH = {"MW": 1, "KW": 1, "SW": 1, "MD": 2, "MF": 2, "KD": 2, "KF": 2}



def _alternation(words: Iterable[str]) -> str:
    """A regex alternation of `words`, longest first (%MSG before %M)."""
    return "|".join(sorted(set(words), key=lambda w: (-len(w), w)))


# field names of more than one letter before their number (%VFC0.TH1): the rest is one letter
_LONG_FIELDS = {f.rstrip("0123456789") for fields in BLOCK_FIELDS.values() for f in fields
                if len(f.rstrip("0123456789")) > 1}
_ADDR = re.compile(
    rf"""%(?P<kind>{_alternation([*SIMPLE_KINDS, *IO_KINDS, *ANALOG_KINDS, *NETWORK_KINDS,
                                  *BLOCK_FIELDS, "L"])})
        (?P<a>\d+)
        (?:\.(?P<b>\d+))?                       # %I0.12 module.channel
        (?:\.(?P<c>\d+))?                       # %I1.0.3 a remote I/O's station.0.channel
        (?:\.(?P<field>{_alternation(_LONG_FIELDS)}|[A-Z])(?P<fbit>\d+)?)?  # %TM0.Q, .TH1
        (?::X(?P<bit>\d+))?                     # %MW3:X5
        (?::(?P<length>\d+))?                   # %MW0:10 table / bit string
        (?:\[(?P<offset>%MW\d+)\])?             # %MW2[%MW5]
    $""",
    re.X | re.I,
)


@dataclass(frozen=True)
class Ref:
    """A resolved object address."""

    kind: str
    index: int  # object number; for %I/%Q the flat channel (module * stride + channel)
    module: int | None = None
    channel: int | None = None
    field: str | None = None  # function-block field: Q V P D E F S I O J
    bit: int | None = None  # %MWi:Xk or %SBRi.Jk
    length: int | None = None  # %MWi:L tables, %Mi:L bit strings
    offset: Ref | None = None  # %MWi[%MWj]
    # %Ix.0.z / %Qx.0.z: the Remote Link station x of a remote I/O controller (its base I/O
    # on the master; the flat index as if it were module expansion_slots + x)
    station: int | None = None
    # the object's symbol (softplc.twido.symbols), for the views; not part of its identity
    symbol: str | None = dc_field(default=None, compare=False, repr=False)

    def with_symbol(self, name: str | None) -> Ref:
        return replace(self, symbol=name)

    @property
    def label(self) -> str:
        """`MOTOR(%Q0.0)` when the object has its symbol attached, else `%Q0.0`: how
        messages and tables name an object (the address alone stays its identity)."""
        return f"{self.symbol}({self})" if self.symbol else str(self)

    @property
    def type(self) -> str:
        if self.bit is not None:
            return BOOL
        if self.kind in BLOCK_FIELDS:
            if self.field is None:
                return "block"
            return BLOCK_FIELDS[self.kind][self.field][0]
        if self.kind in IO_KINDS:
            return BOOL
        if self.kind in ANALOG_KINDS or self.kind in NETWORK_KINDS:
            return INT16
        return SIMPLE_KINDS[self.kind]

    @property
    def writable(self) -> bool:
        if self.kind in READ_ONLY_KINDS:
            return False
        if self.kind in BLOCK_FIELDS:
            if self.field == "J":
                return True  # %SBRi.j and %SCi.j bits can be written [manual]
            return self.field is not None and BLOCK_FIELDS[self.kind].get(
                self.field, (BOOL, False))[1]
        return True

    @property
    def is_block(self) -> bool:
        return self.kind in BLOCK_FIELDS and self.field is None

    def __str__(self) -> str:
        if self.station is not None:
            s = f"%{self.kind}{self.station}.{self.module}.{self.channel}"
        elif self.kind in IO_KINDS or self.kind in ANALOG_KINDS or self.kind in NETWORK_KINDS:
            s = f"%{self.kind}{self.module}.{self.channel}"
        else:
            s = f"%{self.kind}{self.index}"
        if self.field == "J":
            s += f".{self.bit}"  # %SBR0.3, TwidoSuite's spelling
        elif self.field is not None:
            s += f".{self.field}"
        elif self.bit is not None:
            s += f":X{self.bit}"
        if self.length is not None:
            s += f":{self.length}"
        if self.offset is not None:
            s += f"[{self.offset}]"
        return s


# Bits of a shift register (%SBRi.0-15) and of a step counter (%SCi.0-255) [manual].
BLOCK_BITS = {f.kind: f.bits for f in catalog.addressable() if f.bits}


def _block_bit(kind: str, a: int, k: int, text: str, profile: Profile) -> Ref:
    count = profile.count(kind)
    if a >= count:
        raise AddressError(f"{text!r} is beyond the controller profile ({profile.name} has "
                           f"%{kind}0..%{kind}{count - 1})")
    if k >= BLOCK_BITS[kind]:
        raise AddressError(f"{text!r}: bit {k} out of range: %{kind}{a}.0 .. "
                           f"%{kind}{a}.{BLOCK_BITS[kind] - 1}")
    return Ref(kind, a, field="J", bit=k)


def _module_channel(kind: str, a: int, b: str | None, text: str,
                    profile: Profile) -> tuple[int, int]:
    """%Im.c, %QWm.c...: (module, channel), the module within the profile's slots."""
    if b is None:
        raise AddressError(f"{text!r}: I/O addresses are %{kind}module.channel")
    if a > profile.expansion_slots:
        raise AddressError(f"{text!r}: module {a} beyond the "
                           f"{profile.expansion_slots} expansion slots of {profile.name}")
    return a, int(b)


def _network_word(kind: str, station: int, word: str | None, text: str,
                  suffix: bool) -> Ref:
    """%INWi.j / %QNWi.j: station i 0..7, word j 0..3."""
    if word is None or suffix:
        raise AddressError(f"{text!r}: Remote Link words are %{kind}i.j (i the station "
                           f"0..{LINK_STATIONS - 1}, j the word 0..{LINK_WORDS - 1})")
    j = int(word)
    if station >= LINK_STATIONS or j >= LINK_WORDS:
        raise AddressError(f"{text!r}: Remote Link words are %{kind}0.0 .. "
                           f"%{kind}{LINK_STATIONS - 1}.{LINK_WORDS - 1}")
    return Ref(kind, station * LINK_WORDS + j, station, j)


def _remote_io(kind: str, station: int, base: int, channel: int, text: str,
               profile: Profile, suffix: bool) -> Ref:
    """%Ix.0.z / %Qx.0.z: channel z of the base I/O of the remote I/O controller at Remote
    Link address x [manual, from memory, low-medium: docs/twido.md#remote-link;
    only the base is reachable, its size taken as this profile's base]."""
    limit = profile.inputs_base if kind == "I" else profile.outputs_base
    if suffix:
        raise AddressError(f"{text!r}: remote I/O bits take no suffix")
    if not 1 <= station < LINK_STATIONS or base != 0 or channel >= limit:
        raise AddressError(f"{text!r}: a remote I/O channel is %{kind}x.0.z, x the remote's "
                           f"address 1 .. {LINK_STATIONS - 1}, z its base channel 0 .. "
                           f"{limit - 1}")
    slot = profile.expansion_slots + station
    return Ref(kind, slot * profile.channels_per_module + channel, 0, channel, station=station)


def remote_io_slot(profile: Profile, station: int) -> int:
    """The first flat index of remote I/O station `station`'s channels."""
    return (profile.expansion_slots + station) * profile.channels_per_module


#: Characters of one address: the longest Twido address, an indexed double-word bit such
#: as `%MD2999[%MW2999]:X31`, has 22; numbers longer than any index are refused before
#: their conversion.
MAX_ADDRESS_CHARS = 40


def parse_address(text: str, profile: Profile = DEFAULT_PROFILE) -> Ref:
    """Parse and range-check an address. Raises AddressError with a readable message."""
    t = text.strip().replace(" ", "")
    if len(t) > MAX_ADDRESS_CHARS:  # before int() of its numbers
        raise AddressError(f"malformed address {text[:20]!r}...: {len(t)} characters, at "
                           f"most {MAX_ADDRESS_CHARS}")
    m = _ADDR.match(t)
    if not m:
        raise AddressError(f"malformed address {text!r}")
    kind = m["kind"].upper()
    a = int(m["a"])
    field = m["field"].upper() if m["field"] else None
    bit = int(m["bit"]) if m["bit"] is not None else None
    length = int(m["length"]) if m["length"] is not None else None
    offset = parse_address(m["offset"], profile) if m["offset"] else None
    if kind in ANALOG_KINDS:
        module, channel = _module_channel(kind, a, m["b"], text, profile)
        if channel >= ANALOG_STRIDE:
            raise AddressError(f"{text!r}: analog channel {channel} beyond "
                               f"{ANALOG_STRIDE - 1}")
        if field or bit is not None or offset or length is not None:
            raise AddressError(f"{text!r}: analog I/O words take no suffix")
        return Ref(kind, module * ANALOG_STRIDE + channel, module, channel)
    if m["c"] is not None:
        if kind not in IO_KINDS:
            raise AddressError(f"malformed address {text!r}")
        return _remote_io(kind, a, int(m["b"]), int(m["c"]), text, profile,
                          bool(field or bit is not None or offset or length is not None))
    if kind in NETWORK_KINDS:
        return _network_word(kind, a, m["b"], text, bool(field or bit is not None or offset
                                                         or length is not None))
    if kind == "L":
        raise AddressError(f"{text!r} is a label, not an object")

    if kind in IO_KINDS:
        module, channel = _module_channel(kind, a, m["b"], text, profile)
        limit = (profile.inputs_base if kind == "I" else profile.outputs_base) if module == 0 \
            else profile.channels_per_module
        if channel >= limit:
            raise AddressError(f"{text!r}: module {module} has {limit} "
                               f"{'inputs' if kind == 'I' else 'outputs'}")
        if field or bit is not None or offset:
            raise AddressError(f"{text!r}: I/O bits take no suffix but a length (:L)")
        if length is not None and channel + length > limit:
            raise AddressError(f"{text!r}: the bit string runs past channel {limit - 1}")
        return Ref(kind, module * profile.channels_per_module + channel, module, channel,
                   length=length)

    if m["b"] is not None and kind in BLOCK_BITS and not (m["field"] or bit is not None
                                                           or length or offset):
        # %SBRi.j / %SCi.j: TwidoSuite's spelling of bit j [manual]; %SBRi.Jj is the same
        return _block_bit(kind, a, int(m["b"]), text, profile)
    if m["b"] is not None:
        raise AddressError(f"malformed address {text!r}")
    base_kind = WORD_FAMILY.get(kind, kind)
    count = profile.count(base_kind)
    width = WIDTH.get(kind, 1)
    top = a + (length or 1) * width if length else a + width
    if top > count:
        raise AddressError(f"{text!r} is beyond the controller profile "
                           f"({profile.name} has %{base_kind}0..%{base_kind}{count - 1})")

    if kind == "MSG" and a == 0:  # the ports are 1..3 [manual]
        raise AddressError(f"{text!r}: the exchange blocks are %MSG1 .. %MSG{count - 1}")
    if kind in BLOCK_FIELDS:
        fields = BLOCK_FIELDS[kind]
        if field is not None:
            if kind in BLOCK_BITS:
                if field != "J" or m["fbit"] is None:
                    raise AddressError(f"{text!r}: %{kind} bits are %{kind}{a}.j "
                                       f"(or .Jj)")
                return _block_bit(kind, a, int(m["fbit"]), text, profile)
            if m["fbit"] is not None and field + m["fbit"] in fields:  # %VFCi.S0: one name
                field = field + m["fbit"]
            elif field not in fields or m["fbit"] is not None:
                field = "?"
            if field not in fields:
                raise AddressError(f"{text!r}: %{kind} has fields "
                                   f"{', '.join('.' + f for f in fields)}")
        if bit is not None or offset or length:
            raise AddressError(f"malformed address {text!r}")
        return Ref(kind, a, field=field)

    if field is not None:
        raise AddressError(f"{text!r}: %{kind} has no field .{field}")
    if bit is not None:
        if kind not in ("MW", "KW", "SW") or bit > 15:
            raise AddressError(f"{text!r}: bit selection is %MWi:Xk with k in 0..15")
        if offset or length:
            raise AddressError(f"malformed address {text!r}")
    if offset is not None and (kind not in ("MW", "MD", "MF", "KW", "KD", "KF", "M")
                               or offset.kind != "MW"):
        raise AddressError(f"{text!r}: only %M, %MW, %MD, %MF, %KW, %KD, %KF can be indexed "
                           f"by a %MW")
    return Ref(kind, a, bit=bit, length=length, offset=offset)


def expand(text: str, profile: Profile = DEFAULT_PROFILE) -> list[Ref]:
    """An address or a range as single objects: `%MW0:3` -> %MW0 %MW1 %MW2, `%MF4:2` ->
    %MF4 %MF6, `%Q1.0:8` -> 8 output bits from %Q1.0."""
    ref = parse_address(text, profile)
    if ref.length is None:
        return [ref]
    if ref.kind in IO_KINDS:
        assert ref.module is not None and ref.channel is not None
        return [replace(ref, index=ref.index + k, channel=ref.channel + k, length=None)
                for k in range(ref.length)]
    step = WIDTH.get(ref.kind, 1)
    return [Ref(ref.kind, ref.index + k * step) for k in range(ref.length)]
