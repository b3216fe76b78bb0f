"""The environment `softplc verify` assumes: who else writes the objects a program reads.

Between two scans a Modbus host writes %Mn (coil n) and %MWn (register n)
(`modbus.regmap`: [manual, TWD USE 10AE]) except in the configured `[modbus] read_only`
ranges, and each simulated device writes its status words (`Device.read_only_words`). An
object the program reads and never writes that one of them can write is free: any value
at the start of every scan, so that a proof never rests on a SCADA start bit staying 0.
A requirement file keeps such an object at its cold-start value with `held = [...]`, and
declares `host = [...]` for words both a host and the program write (a handshake).
What the program reads, never writes and nothing else can write is held at its cold-start
value, and said so: a requirement proven only because of it is flagged (`vacuity`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from softplc.compiler.resolve import READ, READ_WRITE, object_uses
from softplc.modbus.regmap import COILS, REGISTERS, ReadOnly, span
from softplc.twido.address import Ref

HOST = "a Modbus host"
INDEXED = "%MW[]"  # the model's key of the %MW words written through an index


@dataclass
class Environment:
    """What the model takes from outside the program, per state key."""

    free: dict[str, str] = field(default_factory=dict)  # key -> who writes it
    held: dict[str, str] = field(default_factory=dict)  # key -> why it never changes
    declared_held: set[str] = field(default_factory=set)  # `held = [...]` of the file

    def lines(self, model: Any) -> list[str]:
        """The environment in one short block (what the proofs take as given)."""
        inputs = sorted(k for k in model.inputs if k.startswith("%I"))
        host = sorted(k for k in model.host if k not in self.free)
        system = [f"{k} ({why})" for k, why in model.sys_free.items() if k in model.vars]
        out = ["environment assumed in every scan:"]
        if inputs:
            out.append("  free inputs: " + compact(inputs))
        by_who: dict[str, list[str]] = {}
        for k, who in self.free.items():
            by_who.setdefault(who, []).append(k)
        for who, keys in by_who.items():
            out.append(f"  free, written by {who} (read, never written by the program): "
                       + compact(keys) + "  [held = [...] keeps one at its cold start]")
        if host:
            out.append("  written by a host (declared host/free): " + compact(host))
        if self.held:
            out.append("  held at the cold-start value: " + ", ".join(
                f"{k} ({why})" for k, why in self.held.items()))
        if system:
            out.append("  free system objects: " + ", ".join(system))
        abstracted = model.abstract.where
        if abstracted:
            out.append("  abstracted (any value of its documented range where the engine "
                       "may change it): " + ", ".join(abstracted.values()))
        return out if len(out) > 1 else []


def compact(keys: list[str]) -> str:
    """Keys as text, runs of consecutive %Mn / %MWn joined: %MW0..%MW9."""
    def split(k: str) -> tuple[str, int]:
        head = k.rstrip("0123456789")
        tail = k[len(head):]
        return (head, int(tail)) if tail and head in ("%M", "%MW") else (k, -1)

    parts: list[str] = []
    run: list[tuple[str, int]] = []

    def flush() -> None:
        if run:
            a, b = run[0], run[-1]
            parts.append(f"{a[0]}{a[1]}" if len(run) == 1 else
                         f"{a[0]}{a[1]}..{b[0]}{b[1]}")
            run.clear()
    for k in sorted(keys, key=lambda k: split(k)):
        h, n = split(k)
        if n < 0:
            flush()
            parts.append(k)
            continue
        if run and (run[-1][0] != h or run[-1][1] + 1 != n):
            flush()
        run.append((h, n))
    flush()
    return " ".join(parts)


def writers(read_only: ReadOnly, device_words: dict[str, list[tuple[int, int]]]
            ) -> Any:
    """A function: the state key of a %Mn / %MWn -> who may write it between scans (a
    device, a Modbus host) or None (nobody but the program)."""
    def who(key: str) -> str | None:
        if key.startswith("%MW") and key[3:].isdigit():
            n = int(key[3:])
            for name, ranges in device_words.items():
                if any(a <= n < b for a, b in ranges):
                    return f"device {name}"
            return None if read_only.blocks(REGISTERS, n, 1) else HOST
        if key.startswith("%M") and key[2:].isdigit():
            return None if read_only.blocks(COILS, int(key[2:]), 1) else HOST
        return None
    return who


def keys_of(ref: Ref) -> list[str]:
    """The state keys of a %M bit or %MW word object (a %MD, %MF: both words; a word's bit:
    the word; a bit string: its bits); [] for anything else."""
    where = span(Ref(ref.kind, ref.index, length=ref.length))
    if where is None:
        return []
    space, start, count = where
    prefix = "%M" if space == COILS else "%MW"
    return [f"{prefix}{start + k}" for k in range(count)]


def program_reads(program: Any) -> set[str]:
    """The state keys of the %M bits and %MW words the program reads; indexed objects left
    out."""
    out: set[str] = set()
    for ref, (role, _pos) in object_uses(program).items():
        if role in (READ, READ_WRITE) and ref.offset is None:
            out.update(keys_of(ref))
    return out


def decide(program: Any, written: dict[str, Any], who: Any, held: set[str],
           host: set[str], required: set[str] = frozenset()) -> Environment:
    """The environment of a program: `written` the keys it writes (the model's), `who`
    from `writers`, `held` / `host` the requirement file's declarations, `required` the
    keys the requirements read (one the program never reads is still a host's to write:
    a proof must not rest on it staying 0)."""
    env = Environment(declared_held=set(held))
    indexed = INDEXED in written  # any %MW may be the one written: none is free
    for key in sorted(program_reads(program) | set(required)):
        if key in written or key in host or indexed and key.startswith("%MW"):
            continue
        w = who(key)
        if key in held:
            env.held[key] = "declared held"
        elif w is None:
            env.held[key] = "nothing else writes it"
        else:
            env.free[key] = w
    return env


def vacuity_hint(held: dict[str, str], cone: set[str]) -> list[str]:
    """The held objects a requirement's proof reads (its cone of influence)."""
    return [k for k in held if k in cone]


def of_plc(plc: Any, devices: dict[str, list[tuple[int, int]]] | None = None) -> Any:
    """`writers` for a loaded PLC: its configured read-only ranges, and the status words
    of `devices` (None: of the PLC's own simulated devices, none when loaded without)."""
    from softplc.modbus.tags import host_read_only
    read_only, own = host_read_only(plc)
    return writers(read_only, own if devices is None else devices)


def device_words(program: Any, config: Any) -> dict[str, list[tuple[int, int]]]:
    """The status words each configured device writes: the machine built with its devices
    only to ask them (no scan runs)."""
    from softplc.modbus.tags import host_read_only
    from softplc.plc import PLC
    if config is None:
        return {}
    with PLC.from_file(program, config) as plc:
        return host_read_only(plc)[1]
