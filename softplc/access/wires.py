"""A controller's end of its hardwired signals over TCP (`softplc run --wire-listen`,
softplc.runtime.wiretcp; docs/decisions/wires-over-tcp.md).

Who may drive a wired input: only the plant host (`--wire-peer ADDR`): a connection from
any other address is closed before a byte is read. One connection at a time (a new one
from the plant host, e.g. after its restart, replaces the old), frames of a fixed size
(the layout's), a read timeout: a client costs one thread and a few bytes.

The inputs change only through the access port's one command queue (`Write` records,
applied at the scan boundary like a web monitor's write): a frame queues the inputs that
changed since the last queued values, nothing when none did. The other front-ends may not
write a wired input (the access port refuses it, as a device-driven input), only force it.

A broken wire is a defined state: when the plant host's connection ends (it was killed,
the cable cut) or sends no frame for `hold_s` (wiretcp.HOLD_S), every wired input is
queued to 0 (an open circuit reads 0), until the plant host sends again.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import struct
import threading
from collections.abc import Sequence
from typing import Any

from softplc.access.commands import Write
from softplc.access.errors import AccessError
from softplc.runtime.linktcp import _hang_up, _listen, _Listening
from softplc.runtime.wiretcp import (
    HOLD_S,
    MAX_WIRED,
    OUTPUTS,
    SET,
    WireFrameError,
    encode,
    layout,
    read_frame,
)
from softplc.twido.address import Ref, parse_address

log = logging.getLogger("softplc.wire")


def wired_refs(names: Sequence[str], kind: str, option: str) -> list[Ref]:
    """The %I (or %Q) bits of --wire-in (--wire-out), checked: ValueError says why not."""
    if len(names) > MAX_WIRED:
        raise ValueError(f"{option}: {len(names)} signals, at most {MAX_WIRED}")
    refs = []
    for name in names:
        ref = parse_address(name)  # AddressError (a ValueError) for a malformed one
        if ref.kind != kind or ref.length is not None or ref.bit is not None:
            raise ValueError(f"{option}: {name!r} is not a %{kind} bit (%{kind}0.5...)")
        if ref in refs:
            raise ValueError(f"{option}: {name!r} given twice")
        refs.append(ref)
    return refs


class WireService(_Listening):
    """Listens on `host:port` for the plant host `peer`; drives the `inputs` through the
    access port's queue, answers with the `outputs` of the last scan."""

    def __init__(self, host: str, port: int, peer: str, inputs: Sequence[str],
                 outputs: Sequence[str], hold_s: float = HOLD_S):
        super().__init__()
        self.peer = ipaddress.ip_address(peer)
        self.inputs = wired_refs(inputs, "I", "--wire-in")
        self.outputs = wired_refs(outputs, "Q", "--wire-out")
        if not self.inputs and not self.outputs:
            raise ValueError("--wire-listen: no --wire-in or --wire-out signal")
        self.layout = layout([str(r) for r in self.inputs], [str(r) for r in self.outputs])
        self.hold_s = hold_s
        self.sock = _listen(host, port)
        self.address = self.sock.getsockname()[:2]
        self.access: Any = None  # the daemon's AccessPort (attach_access)
        self.mem: Any = None
        self.queue_lock = threading.Lock()
        self.queued: list[bool] = [False] * len(self.inputs)  # the values last queued
        self.wanted: list[bool] = list(self.queued)  # the values the plant host sent last
        self.out: tuple[bool, ...] = (False,) * len(self.outputs)
        self.conn: socket.socket | None = None
        self.frames = 0
        self.refused = 0  # connections from another address than the plant host's
        self.breaks = 0  # times the wired inputs fell to 0 (connection lost or silent)

    def banner(self) -> str:
        host, port = self.address
        return (f"wires: {len(self.inputs)} inputs ({', '.join(map(str, self.inputs))}) "
                f"driven by {self.peer} only, {len(self.outputs)} outputs, on {host}:{port} "
                f"(TCP; inputs 0 after {self.hold_s:g} s without the plant host)")

    def attach_access(self, plc: Any, access: Any) -> None:
        """Meet the scans through the access port (its queue) and an after_scan hook."""
        self.access = access
        for ref in [*self.inputs, *self.outputs]:
            plc.mem.use_io(ref)
        names = {str(r): "the plant host's wire" for r in self.inputs}
        access.wired.update(names)
        self.mem = plc.mem
        plc.after_scan.append(self.after_scan)
        self.after_scan()

    def after_scan(self) -> None:
        q = self.mem.q_field
        out = tuple(bool(q[r.index]) for r in self.outputs)
        with self.lock:
            self.out = out

    def before_scan(self) -> None:
        pass  # changes go through the access port's queue

    def start(self) -> None:
        self._spawn(self._accept, "wire-listen")

    def _accept(self) -> None:
        while not self.stopping.is_set():
            try:
                conn, addr = self.sock.accept()
            except OSError:
                return  # closed: stopping
            try:
                who = ipaddress.ip_address(addr[0])
            except ValueError:
                who = None
            if who != self.peer:
                self.refused += 1
                log.warning("wires: a connection from %s refused (only %s drives them)",
                            addr[0], self.peer)
                conn.close()
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn.settimeout(self.hold_s)
            with self.lock:  # one plant host: a new connection replaces the old
                old, self.conn = self.conn, conn
            if old is not None:
                _hang_up(old)
            self._spawn(self._serve, "wire-conn", conn)

    def _serve(self, conn: socket.socket) -> None:
        try:
            while not self.stopping.is_set():
                bits = read_frame(conn, SET, self.layout, len(self.inputs))
                with self.lock:
                    self.frames += 1
                    self.wanted = list(bits)
                    out = self.out
                self._queue()
                conn.sendall(encode(OUTPUTS, self.layout, out))
        except (OSError, ConnectionError, WireFrameError, struct.error) as e:
            log.info("wires: the plant host's connection ended (%s): inputs to 0", e)
        finally:
            conn.close()
            with self.lock:
                mine = self.conn is conn
                if mine:
                    self.conn = None
            if mine and not self.stopping.is_set():
                self.cut()

    def cut(self) -> None:
        """The wires are broken: every wired input to 0 (at the next scan boundary)."""
        with self.lock:
            self.wanted = [False] * len(self.inputs)
            self.breaks += 1
        self._queue()

    def _queue(self) -> None:
        """Queue the inputs whose wanted value differs from the last queued one. A full
        queue (a stalled scan) refuses them: they are tried again with the next frame."""
        with self.queue_lock:  # one thread at a time compares and queues
            with self.lock:
                changed = [(k, v) for k, v in enumerate(self.wanted) if v != self.queued[k]]
            if not changed:
                return
            try:
                self.access.queue.put([Write(self.inputs[k], int(v)) for k, v in changed])
            except AccessError as e:
                log.warning("wires: %s", e)
                return
            for k, v in changed:
                self.queued[k] = v
