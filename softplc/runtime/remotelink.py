"""The Twido Remote Link (issue 35): one master (address 0) polls up to 7 remotes (1-7) on
a cycle of its own, not inside a scan [docs/twido.md#remote-link].

A peer controller exchanges 4 words each way with the master: the master's `%QNWi.j`
arrive as peer i's `%INW0.j`, peer i's `%QNW0.j` as the master's `%INWi.j` [A3; names and
indexes manual, from memory]. Peers do not talk to each other. A remote I/O controller runs
no program: the master's outputs `%Qi.0.z` are its base outputs, its base inputs the
master's `%Ii.0.z` [A2; the addressing manual, from memory, low-medium].

The exchange is behind one interface, `Transport.poll(address, request) -> reply | None`,
so that the same master and remotes run in one process over `InMemoryTransport` (the
plant's virtual clock) or, later, between processes over TCP: a transport carries one
`Request` to the remote at `address` and brings back its `Reply`, or None when the remote
did not answer within its slot (not there, stopped answering, the line broken).

Status words [manual, from memory, LOW confidence: the bit layout is a softplc choice until
the TwidoSuite programming guide is checked; every choice is one constant here]:

- `%SW111` (`SW_LINK_STATUS`): on the master, bit i-1 = 1 while remote i answers; on a
  remote, bit a-1 (its own address a) = 1 while the master polls it;
- `%SW112` (`SW_LINK_ERROR`): 0 no error, `ERR_TIMEOUT` a remote expected by the
  configuration (on a remote: the master) missed `MISSES` cycles in a row,
  `ERR_MISMATCH` a remote answered as another type than the configuration says;
- `%SW113` (`SW_LINK_CONFIG`): on the master, bit i-1 = 1 for each remote i the
  configuration declares; on a remote, bit a-1.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Protocol

from softplc.runtime.memory import MemoryImage
from softplc.twido.address import LINK_STATIONS, LINK_WORDS, remote_io_slot

SW_LINK_STATUS, SW_LINK_ERROR, SW_LINK_CONFIG = 111, 112, 113  # [manual, from memory: low]
ERR_NONE, ERR_TIMEOUT, ERR_MISMATCH = 0, 1, 2  # [softplc choice: codes unverified]
# Consecutive unanswered polls after which a remote is shown absent (and, on a remote,
# polls missed after which the master is): a softplc choice, stated in docs/plant.md.
MISSES = 2
# What the master's %INWi.j hold once remote i is absent: its last good words (True) or
# zeros (False). UNVERIFIED (remote-link.md A5: not found); holding is the usual fieldbus
# default and lets a program tell "absent" from "sent 0" only by %SW111.
HOLD_LAST_VALUES = True
MASTER = 0
PEER, REMOTE_IO = "peer", "remote_io"
# Bytes of one poll each way and the line's fixed speed, for the default link cycle: a
# slot per remote of (request + reply) bytes x 10 bits at 38,400 bit/s [speed: manual, from
# memory, remote-link.md A4; frame size: a softplc estimate], rounded up to whole ms.
LINE_BIT_S = 1 / 38_400
FRAME_BYTES = 16
SLOT_US = -(-(2 * FRAME_BYTES * 10 * LINE_BIT_S * 1e6) // 1000) * 1000  # 9 ms


def default_cycle_us(remotes: int) -> int:
    """The master's link cycle for `remotes` remotes (one slot each, one at least)."""
    return int(SLOT_US * max(1, remotes))


@dataclass(frozen=True)
class Request:
    """One poll of the master: the words it sends to a peer (its %QNWi.0-3), or the
    outputs it sets on a remote I/O controller (its %Qi.0.z)."""

    words: tuple[int, ...] = ()
    outputs: tuple[bool, ...] = ()


@dataclass(frozen=True)
class Reply:
    """A remote's answer: its type and the words a peer sends (its %QNW0.0-3) or the
    inputs of a remote I/O controller (its base %I0.z); None: nothing fresh this cycle (a
    slowed link still filling), the master keeps what it had."""

    role: str
    words: tuple[int, ...] | None = None
    inputs: tuple[bool, ...] | None = None


class Transport(Protocol):
    """Carries the master's polls to the remotes. A TCP transport implements the same."""

    def poll(self, address: int, request: Request) -> Reply | None:
        """Send `request` to the remote at `address`; its reply, or None (no answer)."""
        ...


class LinkStation:
    """What the master and a remote share: the memory image, its network words and the
    status words."""

    def __init__(self, mem: MemoryImage, address: int):
        self.mem = mem
        self.address = address

    def _set_status_bit(self, station: int, on: bool) -> None:
        uw, mask = self.mem.sw.uw, 1 << (station - 1)
        uw[SW_LINK_STATUS] = (uw[SW_LINK_STATUS] | mask) if on else \
            (uw[SW_LINK_STATUS] & ~mask & 0xFFFF)

    def _words(self, family: str, station: int) -> tuple[int, ...]:
        w = getattr(self.mem, family).w
        return tuple(w[station * LINK_WORDS + j] for j in range(LINK_WORDS))

    def _put(self, family: str, station: int, words: tuple[int, ...]) -> None:
        w = getattr(self.mem, family).w
        for j, v in enumerate(words[:LINK_WORDS]):
            w[station * LINK_WORDS + j] = v

    def status(self) -> dict[str, int]:
        sw = self.mem.sw.uw
        return {"status": sw[SW_LINK_STATUS], "error": sw[SW_LINK_ERROR],
                "config": sw[SW_LINK_CONFIG]}


class LinkMaster(LinkStation):
    """The master (address 0): one `cycle()` polls every declared remote in address order,
    writes the answers to %INWi.j and keeps %SW111-%SW113."""

    def __init__(self, mem: MemoryImage, remotes: dict[int, str], cycle_us: int):
        super().__init__(mem, MASTER)
        self.remotes = dict(sorted(remotes.items()))
        self.cycle_us = cycle_us
        self.transport: Transport | None = None
        self.missed = {a: MISSES for a in self.remotes}  # absent until a first answer
        self.cycles = 0
        mem.sw.uw[SW_LINK_CONFIG] = sum(1 << (a - 1) for a in self.remotes)
        mem.sw.uw[SW_LINK_STATUS] = 0
        mem.sw.uw[SW_LINK_ERROR] = ERR_NONE

    def cycle(self) -> None:
        self.cycles += 1
        error = ERR_NONE
        for a, role in self.remotes.items():
            reply = None if self.transport is None else \
                self.transport.poll(a, self.request(a, role))
            if reply is not None and reply.role != role:
                error = ERR_MISMATCH
                reply = None
            if reply is None:
                self.missed[a] = min(MISSES, self.missed[a] + 1)
                if self.missed[a] >= MISSES:
                    self._set_status_bit(a, False)
                    error = error or ERR_TIMEOUT
                    if not HOLD_LAST_VALUES:
                        self._put("inw", a, (0,) * LINK_WORDS)
                continue
            self.missed[a] = 0
            self._set_status_bit(a, True)
            if reply.words is not None:
                self._put("inw", a, reply.words)
            if reply.inputs is not None:  # latched by the next scan, as local inputs are
                first = remote_io_slot(self.mem.profile, a)
                n = min(len(reply.inputs), self.mem.profile.inputs_base)
                self.mem.i_field[first:first + n] = reply.inputs[:n]
        self.mem.sw.uw[SW_LINK_ERROR] = error

    def request(self, a: int, role: str) -> Request:
        """The poll for remote `a` from the memory as it stands (the last scan's)."""
        if role == REMOTE_IO:  # the outputs the last scan published
            first = remote_io_slot(self.mem.profile, a)
            return Request(outputs=tuple(
                self.mem.q_field[first:first + self.mem.profile.outputs_base]))
        return Request(self._words("qnw", a))

    def state(self) -> dict[str, Any]:
        """What a link cycle changes here besides memory (for the debugger's `back`)."""
        return {"missed": dict(self.missed), "cycles": self.cycles}

    def set_state(self, st: dict[str, Any]) -> None:
        self.missed, self.cycles = dict(st["missed"]), st["cycles"]

    def present(self, address: int) -> bool:
        return bool(self.mem.sw.uw[SW_LINK_STATUS] >> (address - 1) & 1)


class LinkRemote(LinkStation):
    """A remote (address 1-7): `answer` serves the master's poll; `tick`, once a link cycle,
    notices when the master stopped polling."""

    def __init__(self, mem: MemoryImage, address: int, role: str = PEER):
        super().__init__(mem, address)
        self.role = role
        self.missed = MISSES
        self.polled = False
        mem.sw.uw[SW_LINK_CONFIG] = 1 << (address - 1)
        mem.sw.uw[SW_LINK_STATUS] = 0
        mem.sw.uw[SW_LINK_ERROR] = ERR_NONE

    def answer(self, request: Request | None) -> Reply:
        """The master's poll (None: a poll whose words are still on their way)."""
        self.polled = True
        mem = self.mem
        if self.role == REMOTE_IO:  # no program: the master's outputs are its outputs
            if request is not None:
                n = min(len(request.outputs), mem.profile.outputs_base)
                mem.q[:n] = mem.q_field[:n] = request.outputs[:n]
            return self.reply()
        if request is not None:
            self._put("inw", MASTER, request.words)
        return self.reply()

    def reply(self) -> Reply:
        """What this remote answers from its memory as it stands, changing nothing."""
        if self.role == REMOTE_IO:
            return Reply(self.role, inputs=tuple(self.mem.i_field[:self.mem.profile.inputs_base]))
        return Reply(self.role, self._words("qnw", MASTER))

    def state(self) -> dict[str, Any]:
        """What a link cycle changes here besides memory (for the debugger's `back`)."""
        return {"missed": self.missed, "polled": self.polled}

    def set_state(self, st: dict[str, Any]) -> None:
        self.missed, self.polled = st["missed"], st["polled"]

    def tick(self) -> None:
        self.missed = 0 if self.polled else min(MISSES, self.missed + 1)
        self.polled = False
        here = self.missed < MISSES
        self._set_status_bit(self.address, here)
        self.mem.sw.uw[SW_LINK_ERROR] = ERR_NONE if here else ERR_TIMEOUT


@dataclass
class _Line:
    """One remote's line in the in-memory transport: its endpoint, a delay, broken or not."""

    remote: LinkRemote | None = None
    delay: int = 0  # link cycles each way
    broken: bool = False
    to_remote: deque[Request] = field(default_factory=deque)
    to_master: deque[Reply] = field(default_factory=deque)


class InMemoryTransport:
    """The link inside one process: remotes attached by address. `delay(a, n)` makes the
    words take n more link cycles each way (a slowed link: the polls are still answered);
    `cut(a)` / `mend(a)` break and repair the line to remote a; `detach(a)` is a remote
    gone (killed); `attach` a remote (re)joining."""

    def __init__(self) -> None:
        self.lines: dict[int, _Line] = {a: _Line() for a in range(1, LINK_STATIONS)}

    def attach(self, remote: LinkRemote) -> None:
        line = self.lines[remote.address]
        line.remote = remote
        line.to_remote.clear()
        line.to_master.clear()

    def detach(self, address: int) -> None:
        self.lines[address].remote = None

    def delay(self, address: int, cycles: int) -> None:
        if cycles < 0:
            raise ValueError("a link delay is a number of cycles >= 0")
        self.lines[address].delay = cycles

    def cut(self, address: int) -> None:
        self.lines[address].broken = True

    def mend(self, address: int) -> None:
        self.lines[address].broken = False

    def state(self) -> dict[int, tuple[Any, ...]]:
        """Each line's endpoint, delay, break and words in flight (for `back`)."""
        return {a: (ln.remote, ln.delay, ln.broken, tuple(ln.to_remote), tuple(ln.to_master))
                for a, ln in self.lines.items()}

    def set_state(self, st: dict[int, tuple[Any, ...]]) -> None:
        for a, (remote, delay, broken, to_remote, to_master) in st.items():
            self.lines[a] = _Line(remote, delay, broken, deque(to_remote), deque(to_master))

    def remotes(self) -> list[LinkRemote]:
        return [ln.remote for ln in self.lines.values() if ln.remote is not None]

    def poll(self, address: int, request: Request) -> Reply | None:
        line = self.lines.get(address)
        if line is None or line.remote is None or line.broken:
            return None
        if not line.delay:
            return line.remote.answer(request)
        # a slowed link: the master's words reach the remote `delay` cycles late and the
        # remote's reach the master `delay` cycles after they were sent; until the pipes
        # fill, the poll is answered with no fresh words
        line.to_remote.append(request)
        reply = line.remote.answer(line.to_remote.popleft()
                                   if len(line.to_remote) > line.delay else None)
        line.to_master.append(reply)
        if len(line.to_master) > line.delay:
            return line.to_master.popleft()
        return Reply(reply.role)
