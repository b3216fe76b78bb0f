"""Oscilloscope recordings (.dta: IMCal_.dta, IMMea_.dta), mass-estimation.md §3.3.

INI-like UTF-8 text::

    [SETUP]
    SCOPEMODE=0
    SCOPEMODETEXT="YT"
    COUNT=8192
    SAMPLING=3000                      (µs)
    [CHANNELS]
    CHANNELID1=2  CHANNEL1="s aktualní"  AXIS1="A"  AMPL1=1.000  DIM1="mm"  FACTOR1=1.0000000E-04
    ... (one key per line, channels n = 1..4)
    [DATA]
    raw 0 0 raw 0 0 raw 0 0 raw 0 0    (COUNT lines; per channel in header order)

value = raw x FACTOR, in the channel's DIM; sample i (1-based) is at t_i = i x SAMPLING. The
``[CHANNELS]`` and ``[DATA]`` layout is our choice (the thesis shows only the keys and says
every datum is followed by "0 0").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softplc.errors import MassFileError
from softplc.machines.machining.files import read_text, write_atomic

_KEYS = ("CHANNELID", "CHANNEL", "AXIS", "AMPL", "DIM", "FACTOR")
_QUOTED = {"CHANNEL", "AXIS", "DIM"}


@dataclass(frozen=True)
class Channel:
    id: int
    name: str
    dim: str
    factor: float
    axis: str = "A"
    ampl: float = 1.0  # display amplification only: never applied


# The iTNC channels of the thesis's files (Fig. 3-3): position, velocity, acceleration, torque
THESIS_CHANNELS = (
    Channel(2, "s aktualní", "mm", 1.0e-4),
    Channel(6, "v aktualní", "mm/min", 1.0728836e-1),
    Channel(19, "a aktualní", "m/(s*s)", 5.9604645e-4),
    Channel(29, "M aktual", "Nm", 1.0e-3),
)


@dataclass(frozen=True)
class Recording:
    """COUNT samples of each channel as raw integers (column n = channel n)."""

    channels: tuple[Channel, ...]
    sampling_us: int
    raw: np.ndarray  # shape (count, len(channels)), int64
    name: str = "<recording>"

    @property
    def count(self) -> int:
        return int(self.raw.shape[0])

    def times(self) -> np.ndarray:
        """Sample times in seconds: t_i = i * SAMPLING, i = 1..COUNT."""
        return np.arange(1, self.count + 1, dtype=np.int64) * self.sampling_us * 1e-6

    def channel_index(self, channel_id: int) -> int:
        for i, c in enumerate(self.channels):
            if c.id == channel_id:
                return i
        raise KeyError(channel_id)

    def values(self, channel_id: int) -> np.ndarray:
        """raw x FACTOR of one channel, in the channel's DIM."""
        i = self.channel_index(channel_id)
        return self.raw[:, i] * self.channels[i].factor

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Recording) and self.channels == other.channels
                and self.sampling_us == other.sampling_us
                and np.array_equal(self.raw, other.raw))

    __hash__ = None  # type: ignore[assignment]


def quantise(values: np.ndarray, factor: float) -> np.ndarray:
    """The raw integers a recorder stores for `values` (round to the nearest step)."""
    return np.rint(np.asarray(values, dtype=float) / factor).astype(np.int64)


def format_recording(rec: Recording) -> str:
    out = ["[SETUP]", "SCOPEMODE=0", 'SCOPEMODETEXT="YT"', f"COUNT={rec.count}",
           f"SAMPLING={rec.sampling_us}", "[CHANNELS]"]
    for n, c in enumerate(rec.channels, 1):
        out += [f"CHANNELID{n}={c.id}", f'CHANNEL{n}="{c.name}"', f'AXIS{n}="{c.axis}"',
                f"AMPL{n}={c.ampl:.3f}", f'DIM{n}="{c.dim}"', f"FACTOR{n}={c.factor:.7E}", ""]
    out.append("[DATA]")
    lines = [" ".join(f"{v} 0 0" for v in row) for row in rec.raw.tolist()]
    return "\n".join(out + lines) + "\n"


def write_recording(rec: Recording, path: str | Path) -> None:
    write_atomic(path, format_recording(rec).encode("utf-8"))


def parse_recording(text: str, name: str = "<recording>") -> Recording:
    section = ""
    setup: dict[str, str] = {}
    chan: dict[tuple[str, int], tuple[str, int]] = {}  # (key, n) -> (value, line)
    data_start = 0
    lines = text.splitlines()
    for lineno, raw in enumerate(lines, 1):
        s = raw.strip()
        if not s:
            continue
        if s.startswith("[") and s.endswith("]"):
            section = s[1:-1].upper()
            if section == "DATA":
                data_start = lineno
                break
            continue
        key, eq, val = s.partition("=")
        if not eq:
            raise MassFileError(f"{name}:{lineno}: {s!r}: expected KEY=value")
        key, val = key.strip().upper(), val.strip()
        base = key.rstrip("0123456789")
        if base in _KEYS and base != key:
            chan[(base, int(key[len(base):]))] = (val, lineno)
        else:
            setup[key] = val
    if not data_start:
        raise MassFileError(f"{name}: no [DATA] section")
    try:
        count, sampling = int(setup["COUNT"]), int(setup["SAMPLING"])
    except KeyError as e:
        raise MassFileError(f"{name}: [SETUP] has no {e.args[0]}") from None
    except ValueError:
        raise MassFileError(f"{name}: COUNT={setup.get('COUNT')!r} and SAMPLING="
                            f"{setup.get('SAMPLING')!r}: expected integers") from None
    if count < 1 or sampling < 1:
        raise MassFileError(f"{name}: COUNT={count}, SAMPLING={sampling}: expected >= 1")
    numbers = sorted({n for _, n in chan})
    if numbers != list(range(1, len(numbers) + 1)) or not numbers:
        raise MassFileError(f"{name}: channels numbered {numbers}: expected 1..N")
    channels = []
    for n in numbers:
        def get(key: str, n: int = n) -> tuple[str, int]:
            if (key, n) not in chan:
                raise MassFileError(f"{name}: channel {n} has no {key}{n}")
            v, line = chan[(key, n)]
            return (v[1:-1] if key in _QUOTED and len(v) >= 2 and v[0] == v[-1] == '"'
                    else v), line
        try:
            vals = {k: get(k) for k in _KEYS}
            ch = Channel(int(vals["CHANNELID"][0]), vals["CHANNEL"][0], vals["DIM"][0],
                         float(vals["FACTOR"][0]), vals["AXIS"][0], float(vals["AMPL"][0]))
        except ValueError as e:
            raise MassFileError(f"{name}: channel {n}: {e}") from None
        if not ch.factor > 0:
            raise MassFileError(f"{name}:{vals['FACTOR'][1]}: FACTOR{n}={ch.factor}: "
                                "expected a number > 0")
        channels.append(ch)
    width = 3 * len(channels)
    rows = [s for s in lines[data_start:] if s.strip()]
    numbered = [(n, s) for n, s in enumerate(lines[data_start:], data_start + 1) if s.strip()]
    if len(rows) != count:
        raise MassFileError(f"{name}: {len(rows)} data lines, COUNT={count}")
    try:
        raw = np.array([r.split() for r in rows], dtype=np.int64)
    except ValueError:
        raw = None
    if raw is None or raw.ndim != 2 or raw.shape[1] != width:
        for lineno, r in numbered:
            parts = r.split()
            if len(parts) != width or not all(p.lstrip("-").isdigit() for p in parts):
                raise MassFileError(f"{name}:{lineno}: {r.strip()!r}: expected "
                                    f"{width} integers ('raw 0 0' per channel)")
    return Recording(tuple(channels), sampling, raw[:, ::3].copy(), name)


def read_recording(path: str | Path) -> Recording:
    return parse_recording(read_text(path, "recording"), str(path))
