"""A Modbus TCP host (client) for streaming to a PLC: the connection, one request with
retries and reconnects, register reads and writes, polling until a condition holds.

The drawing table's `DrawClient` (softplc/gcode/host.py) and the cutting table's
`CutClient` (softplc/cutting/client.py) are this with their own register maps and
handshakes. Every failure becomes a `HostError` that says what was being done.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, TextIO

from ..errors import SoftPLCError

# pymodbus logs failed connects itself; without a handler Python would print them raw to
# stderr next to our own message. Records still reach handlers an application installs.
_pymodbus_log = logging.getLogger("pymodbus")
if not _pymodbus_log.handlers:
    _pymodbus_log.addHandler(logging.NullHandler())


class HostError(SoftPLCError):
    """Streaming to the PLC failed (unreachable, timeout, Modbus exception)."""


class ProgressLine:
    """One text line redrawn in place (carriage return) on a text stream (None: silent):
    a bar of `width` characters for a fraction done, then any text."""

    def __init__(self, stream: TextIO | None, width: int = 30):
        self.stream = stream
        self.width = width
        self.shown = False

    def show(self, fraction: float, text: str) -> None:
        if self.stream is None:
            return
        filled = min(self.width, max(0, int(self.width * fraction)))
        self.stream.write(f"\r[{'#' * filled}{'-' * (self.width - filled)}] {text}\x1b[K")
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.stream is not None and self.shown:
            self.stream.write("\n")
            self.stream.flush()
            self.shown = False


class ModbusHost:
    """Connection and requests; use as a context manager (connects on enter) or call
    `connect()` / `close()`."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5020, *, device_id: int = 1,
                 poll_interval: float = 0.05, request_timeout: float = 1.0,
                 retries: int = 3):
        self.host, self.port, self.device_id = host, port, device_id
        self.poll_interval = poll_interval
        self.request_timeout = request_timeout
        self.retries = max(0, retries)
        self._client: Any = None

    @property
    def where(self) -> str:
        return f"{self.host}:{self.port}"

    def connect(self) -> Any:
        from pymodbus.client import ModbusTcpClient

        if self._client is None:
            self._client = ModbusTcpClient(self.host, port=self.port,
                                           timeout=self.request_timeout, retries=0,
                                           reconnect_delay=0, reconnect_delay_max=0)
        try:
            ok = self._client.connect()
        except OSError as e:
            ok, why = False, str(e)
        else:
            why = "connection refused or timed out"
        if not ok:
            self.close()
            raise HostError(f"cannot reach the PLC at {self.where} ({why}); is the softplc "
                            "daemon running and serving Modbus TCP on that port?")
        return self

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    def __enter__(self) -> Any:
        return self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _call(self, what: str, fn: Callable[..., Any], *args: object,
              **kwargs: object) -> Any:
        """One Modbus request, retried with a reconnect on communication failures."""
        from pymodbus.exceptions import ModbusException

        last = ""
        for attempt in range(self.retries + 1):
            if self._client is None:
                try:
                    self.connect()
                except HostError as e:
                    last = str(e)
                    time.sleep(self.poll_interval)
                    continue
            try:
                rr = fn(self._client, *args, device_id=self.device_id, **kwargs)
            except (ModbusException, OSError) as e:
                last = str(e) or type(e).__name__
                self.close()
                if attempt < self.retries:
                    time.sleep(self.poll_interval)
                continue
            if rr.isError():
                raise HostError(f"{what}: the PLC at {self.where} answered with a Modbus "
                                f"exception ({rr})")
            return rr
        raise HostError(f"{what}: no answer from the PLC at {self.where} after "
                        f"{self.retries + 1} attempts ({last})")

    def read_words(self, start: int, count: int) -> list[int]:
        """%MW start .. start+count-1 (FC 3), unsigned as on the wire."""
        what = f"reading %MW{start}-%MW{start + count - 1}"
        rr = self._call(what, lambda c, **kw: c.read_holding_registers(start, count=count,
                                                                         **kw))
        regs = list(rr.registers)
        if len(regs) < count:
            raise HostError(f"{what}: got {len(regs)} registers")
        return regs

    def write_words(self, start: int, values: list[int], what: str) -> None:
        """One FC 16 request from %MW start."""
        self._call(what, lambda c, **kw: c.write_registers(start, values, **kw))

    def write_bit(self, index: int, value: bool, what: str) -> None:
        """%M index (coil, FC 5)."""
        self._call(what, lambda c, **kw: c.write_coil(index, value, **kw))

    def poll(self, read: Callable[[], Any], ready: Callable[[Any], bool], timeout: float,
             what: str, check: Callable[[Any], None] | None = None,
             describe: Callable[[Any], str] = str) -> Any:
        """Call `read()` until `ready(state)`; `check(state)` may raise first (a fault);
        HostError after `timeout` seconds, naming `what` and `describe(state)`."""
        deadline = time.monotonic() + timeout
        while True:
            state = read()
            if check is not None:
                check(state)
            if ready(state):
                return state
            if time.monotonic() >= deadline:
                raise HostError(f"{what}: timed out after {timeout:g} s ({describe(state)})")
            time.sleep(self.poll_interval)
