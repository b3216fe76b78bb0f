"""The host's side of the estimation request over Modbus (mass-estimation.md §6, the
proposed mapping; one place for these word addresses).

The PLC raises a request by incrementing EST_REQ; the host runs a tuning, then writes the
result words and EST_ACK := EST_REQ in ONE FC 16 frame (the server applies a frame whole at
the next scan start, so the PLC never sees the acknowledgement without its data). On a
refusal only EST_ACK and EST_STATUS change: the MP words keep their previous values.

=========  ==============================================================
%MW400     STATE (the PLC's step; read only by the host)
%MW401     EST_REQ (PLC: +1 per request)
%MW402     EST_ACK (host: = EST_REQ when done)
%MW403     EST_STATUS: 0 ok, 1 files, 2 channel IDs, 3 crossings != 8,
           4 singular fit, 5 u/m > Acc_uncert, 6 no table row, 7 other
%MW404     TABLE_ROW
%MW405     AXIS_IDX
%MF406     MASS kg        %MF408 UNCERT kg        %MF410 fitted a m/s²
%MF420..   the 22 MPs of the row in macro order (MP2500, MP2510, then
%MF462     filters 1..5: type, frequency, damping, bandwidth), float32
=========  ==============================================================
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TextIO

from softplc.errors import HostError, MassEstimationError, UncertaintyError
from softplc.machines.machining.params import MP_NAMES
from softplc.machines.machining.tuning import TuneResult
from softplc.modbus.host import ModbusHost
from softplc.modbus_codec import float_to_words

W_STATE, W_REQ, W_ACK, W_STATUS, W_ROW, W_AXIS = 400, 401, 402, 403, 404, 405
F_MASS, F_UNCERT, F_ACCEL = 406, 408, 410
F_MPS = 420
STATUS_OK = 0
RESULT_END = F_MPS + 2 * len(MP_NAMES)  # one past the last MP word (%MW463)


def words(mem: Any) -> dict[str, Any]:
    """The handshake's words as the web monitor's Machine tab shows them, read from a
    memory image between two scans (a float that is not finite reads None)."""
    mw = mem.mw

    def real(i: int) -> float | None:
        v = float(mw.get_f(i))
        return v if math.isfinite(v) else None

    return {"state": int(mw.w[W_STATE]), "requests": int(mw.w[W_REQ]),
            "answers": int(mw.w[W_ACK]), "status": int(mw.w[W_STATUS]),
            "row": int(mw.w[W_ROW]), "mass_kg": real(F_MASS),
            "uncertainty_kg": real(F_UNCERT), "accel": real(F_ACCEL)}


def result_words(req: int, res: TuneResult) -> list[int]:
    """%MW402..%MW463: EST_ACK, status 0, row, axis, mass, uncertainty, a, the 22 MPs."""
    words = [0] * (RESULT_END - W_ACK)

    def put(addr: int, regs: Sequence[int]) -> None:
        words[addr - W_ACK:addr - W_ACK + len(regs)] = regs

    e = res.estimate
    put(W_ACK, [req, STATUS_OK, res.row.number, int(res.values[0])])
    for addr, v in ((F_MASS, e.mass), (F_UNCERT, e.uncertainty), (F_ACCEL, e.acceleration)):
        put(addr, float_to_words(v))
    for i, v in enumerate(res.mp_values()):
        put(F_MPS + 2 * i, float_to_words(v))
    return words


def error_words(req: int, err: MassEstimationError) -> list[int]:
    """%MW402..%MW403: EST_ACK and the refusal's status (MP words untouched)."""
    return [req, err.status]


@dataclass
class Served:
    request: int
    status: int
    message: str


def serve(host: ModbusHost, run: Callable[[], TuneResult], *, once: bool = False,
          timeout: float | None = None, log: TextIO | None = None) -> list[Served]:
    """Answer the PLC's estimation requests until `once` is done or `timeout` seconds
    pass without a request (None: forever; Ctrl-C stops). Progress goes to `log`
    (default stderr)."""
    log = log or sys.stderr
    served: list[Served] = []
    last_seen = time.monotonic()
    while True:
        req, ack = host.read_words(W_REQ, 2)
        if req != ack:
            try:
                res = run()
            except MassEstimationError as e:
                host.write_words(W_ACK, error_words(req, e))
                extra = ""
                if isinstance(e, UncertaintyError) and e.estimate is not None:
                    extra = " (estimate not used)"
                served.append(Served(req, e.status, f"{e}{extra}"))
            else:
                host.write_words(W_ACK, result_words(req, res))
                served.append(Served(req, STATUS_OK, res.summary()))
            s = served[-1]
            print(f"request {s.request}: status {s.status}\n{s.message}", file=log)
            if once:
                return served
            last_seen = time.monotonic()
        elif timeout is not None and time.monotonic() - last_seen > timeout:
            if once:
                raise HostError(f"no estimation request (%MW{W_REQ} != %MW{W_ACK}) from the "
                                f"PLC at {host.where} within {timeout:g} s")
            return served
        time.sleep(host.poll_interval)
