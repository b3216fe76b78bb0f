"""A Modbus TCP host (client) talking to the soft Twido: connection, retries and the word
helpers the host programs share (`softplc draw`, `softplc tune`, `softplc cut`), polling
until a condition holds, and the one-line progress display."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from typing import Any, Self, TextIO

from softplc.errors import HostError
from softplc.modbus_codec import float_to_words, words_to_float

# pymodbus logs failed connects itself; without a handler Python would print them raw to
# stderr next to our own message. Records still reach handlers an application installs.
_pymodbus_log = logging.getLogger("pymodbus")
if not _pymodbus_log.handlers:
    _pymodbus_log.addHandler(logging.NullHandler())


class ProgressLine:
    """A progress line on a text stream (None: silent): a bar of `width` characters for a
    fraction done, then any text. On a terminal the line is redrawn in place (carriage
    return); written to a pipe or a file it is a plain line every `LINE_INTERVAL_S` seconds
    (and the first and the last), so a log holds a readable history, not one line of
    hundreds of carriage-return frames."""

    LINE_INTERVAL_S = 5.0  # off a terminal: a line at most this often

    def __init__(self, stream: TextIO | None, width: int = 30,
                 clock: Callable[[], float] = time.monotonic):
        self.stream = stream
        self.width = width
        self.shown = False
        self._clock = clock
        isatty = getattr(stream, "isatty", None)
        self.tty = bool(isatty and isatty())
        self._last_line: float | None = None  # off a terminal: when the last line went out
        self._pending: str | None = None  # off a terminal: the newest text not written

    def show(self, fraction: float, text: str) -> None:
        if self.stream is None:
            return
        filled = min(self.width, max(0, int(self.width * fraction)))
        line = f"[{'#' * filled}{'-' * (self.width - filled)}] {text}"
        if self.tty:
            self.stream.write(f"\r{line}\x1b[K")
        else:
            now = self._clock()
            if self._last_line is not None and fraction < 1 \
                    and now - self._last_line < self.LINE_INTERVAL_S:
                self._pending = line
                return
            self.stream.write(line + "\n")
            self._last_line, self._pending = now, None
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.stream is None:
            return
        if self._pending is not None:  # off a terminal: the last state is always written
            self.stream.write(self._pending + "\n")
            self._pending = None
            self.stream.flush()
        elif self.tty and self.shown:
            self.stream.write("\n")
            self.stream.flush()
        self.shown = False


class ModbusHost:
    """pymodbus' blocking TCP client with reconnecting retries; every failure becomes a
    `HostError`. Use as a context manager (connects on enter) or `connect()` / `close()`."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5020, *, device_id: int = 1,
                 poll_interval: float = 0.05, request_timeout: float = 1.0,
                 retries: int = 3):
        self.host, self.port, self.device_id = host, port, device_id
        self.poll_interval = poll_interval
        self.request_timeout = request_timeout
        self.retries = max(0, retries)
        self._client = None

    # -- connection --------------------------------------------------------------------
    @property
    def where(self) -> str:
        return f"{self.host}:{self.port}"

    def connect(self) -> Self:
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

    def connect_within(self, timeout: float, notice: Callable[[str], None] | None = None,
                       ) -> Self:
        """`connect()`, retried every poll interval for up to `timeout` s: a host started
        before the daemon listens waits for it. `notice` gets one message on the first
        refusal; the last refusal's HostError is raised when the time is up."""
        end = time.monotonic() + timeout
        while True:
            try:
                return self.connect()
            except HostError:
                if time.monotonic() >= end:
                    raise
                if notice is not None:
                    notice(f"waiting up to {timeout:g} s for the PLC at {self.where} ...")
                    notice = None
                time.sleep(max(self.poll_interval, 0.1))

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    def __enter__(self) -> Self:
        return self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _call(self, what: str, fn: Callable[..., object], *args: object,
              **kwargs: object) -> object:
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

    # -- words -------------------------------------------------------------------------
    def read_words(self, address: int, count: int) -> list[int]:
        """%MW<address>.. (FC 3), unsigned 16-bit values."""
        rr = self._call(f"reading %MW{address}:{count}",
                        lambda c, **kw: c.read_holding_registers(address, count=count, **kw))
        regs = list(rr.registers)  # type: ignore[attr-defined]
        if len(regs) != count:
            raise HostError(f"reading %MW{address}:{count}: got {len(regs)} registers")
        return regs

    def write_words(self, address: int, values: Sequence[int]) -> None:
        """%MW<address>.. in one FC 16 frame (lands whole at the next scan start)."""
        words = [v & 0xFFFF for v in values]
        self._call(f"writing %MW{address}:{len(words)}",
                   lambda c, **kw: c.write_registers(address, words, **kw))

    def read_float(self, address: int) -> float:
        """%MF<address> (two registers, low word first)."""
        return words_to_float(*self.read_words(address, 2))

    def write_float(self, address: int, value: float) -> None:
        self.write_words(address, float_to_words(value))

    def write_bit(self, index: int, value: bool) -> None:
        """%M<index> (coil, FC 5)."""
        self._call(f"writing %M{index}", lambda c, **kw: c.write_coil(index, value, **kw))

    # -- waiting -----------------------------------------------------------------------
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
