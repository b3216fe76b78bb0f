"""Counterexamples in the real scan engine: replay, cex.json, an emitted pytest test, and
the REPL's `--replay` hook.

A counterexample is the inputs of each scan from a cold start (%I bits, analog %IW words,
host-written words, set before the scan as the field and a host would) and the values the
model computed for every object it models. `replay` runs the same scans in a `PLC` and
lists every object whose value differs: engine and model must agree exactly.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from softplc.errors import SoftPLCError
from softplc.twido.address import REAL
from softplc.twido.semantics import IntDomain
from softplc.verify.checker import evaluate, response_step
from softplc.verify.requirements import parse_check

CEX_FORMAT = "softplc-cex/1"
#: A float a requirement reads that is no JSON number: written as its text
NOT_FINITE = ("nan", "inf", "-inf")


def shown(v: Any) -> Any:
    """A value as a counterexample holds it: a NaN or an infinity (a %MF a requirement
    reads) as "nan", "inf", "-inf" (JSON has no such numbers: `read_cex` refuses them)."""
    return str(v) if isinstance(v, float) and not math.isfinite(v) else v


def set_inputs(plc: Any, inputs: dict[str, int]) -> None:
    """Set a scan's inputs, system words the model leaves free included: the clock
    words and schedule outputs come from the counterexample, so the real-time clock
    stops rewriting them (`verify.system`)."""
    rtc = plc.engine.rtc
    if rtc is not None and "tick" not in vars(rtc):
        rtc.tick = _clock_held
    for k, v in inputs.items():
        if k == "period_ms":  # this scan's length (a variable period)
            plc.set_scan_period(v / 1000)
        elif k.startswith("%IW"):
            plc.mem.write(k, v)
        else:
            plc[k] = v


def _clock_held(now_us: int) -> None:
    """The real-time clock's tick while a counterexample sets its words."""


def replay(plc: Any, trace: list[dict[str, Any]]) -> list[str]:
    """Run the counterexample's scans on a cold-started `plc`; the disagreements."""
    out = []
    for n, row in enumerate(trace, 1):
        set_inputs(plc, row["inputs"])
        plc.scan()
        for k, want in row["objects"].items():
            got = int(plc[k])
            if got != want:
                out.append(f"scan {n}: {k} = {got} in the engine, {want} in the model")
    return out


def first_failure(plc: Any, check: str, scans: list[dict[str, int]]) -> int | None:
    """Replay inputs on `plc` and evaluate the requirement on the engine's values after
    each scan: the first scan (from 1) where it fails, or None."""
    def err(msg: str, col: int, code: object = None) -> SoftPLCError:
        return SoftPLCError(f"{check!r}: {msg} (column {col})")
    req = parse_check(check, check, plc.symbols, err)  # names as written
    count, prev = 0, False
    n_resp = req.within if req.within >= 0 else (-req.within * 1000) // round(
        plc.scan_period * 1e6)

    def read(ref: Any) -> int | float:
        v = plc.mem.read(ref)
        return float(v) if ref.type == REAL else int(v)  # a %MF, %KF: the single's value
    for n, inputs in enumerate(scans, 1):
        set_inputs(plc, inputs)
        plc.scan()
        if req.kind == "always":
            if not evaluate(IntDomain, req.cond, read):
                return n
            continue
        x = bool(evaluate(IntDomain, req.cond, read))
        y = bool(evaluate(IntDomain, req.target, read))
        count, prev = response_step(IntDomain, count, prev, x, y, n_resp), x
        if count > n_resp:
            return n
    return None


def write_cex(path: Path, program: Path, config: Path | None,
              items: list[dict[str, Any]]) -> None:
    path.write_text(json.dumps({"format": CEX_FORMAT, "program": str(program),
                                "config": str(config) if config else None,
                                "counterexamples": items}, indent=1) + "\n")


MAX_CEX_BYTES = 16 * 1024 * 1024  # a cex.json read back (DEPTH scans write ~10 KB)
MAX_CEX_SCANS = 5000  # scans of one counterexample (far beyond any --depth BMC reaches)
MAX_CEX_INPUTS = 1000  # inputs set in one scan
MAX_NAME = 40  # characters of an address or a symbol in a counterexample
# a scan's length: %SW0 holds it in ms, a signed word (PLC.set_scan_period clamps to it)
MAX_CEX_PERIOD_MS = 32767


def _finite(text: str) -> float:
    raise ValueError(f"{text} is not a finite number")


def _check_cex(path: Path, items: Any) -> None:
    """The shape `replay_hook` and the trace player rely on, or a clear error."""
    if not isinstance(items, list) or not items:
        raise SoftPLCError(f"{path}: no counterexample in it")
    for i, it in enumerate(items, 1):
        where = f"{path}: counterexample {i}"
        if not isinstance(it, dict) or not isinstance(it.get("check"), str) \
                or not isinstance(it.get("scans"), list) or not it["scans"]:
            raise SoftPLCError(f"{where}: needs \"check\" (text) and \"scans\" (a list)")
        if len(it["scans"]) > MAX_CEX_SCANS:
            raise SoftPLCError(f"{where}: {len(it['scans'])} scans, at most {MAX_CEX_SCANS}")
        if not isinstance(it.get("requirement", ""), str):
            raise SoftPLCError(f"{where}: \"requirement\" is its name (text)")
        for n, row in enumerate(it["scans"], 1):
            if not isinstance(row, dict):
                raise SoftPLCError(f"{where}, scan {n}: an object with \"inputs\"")
            for key in ("inputs", "values"):  # values: what the requirement reads
                if not _numbers(row.get(key, {} if key == "values" else None),
                                NOT_FINITE if key == "values" else ()):
                    raise SoftPLCError(f"{where}, scan {n}: \"{key}\" maps at most "
                                       f"{MAX_CEX_INPUTS} addresses to numbers")
            period = row["inputs"].get("period_ms", 1)
            if not 1 <= period <= MAX_CEX_PERIOD_MS:
                raise SoftPLCError(f"{where}, scan {n}: period_ms {period!r}: from 1 to "
                                   f"{MAX_CEX_PERIOD_MS}")


def _numbers(d: Any, texts: tuple[str, ...] = ()) -> bool:
    return isinstance(d, dict) and len(d) <= MAX_CEX_INPUTS and all(
        isinstance(k, str) and len(k) <= MAX_NAME and (isinstance(v, int | float)
                                                      or v in texts)
        for k, v in d.items())


def read_cex(path: Path) -> dict[str, Any]:
    try:
        if Path(path).stat().st_size > MAX_CEX_BYTES:
            raise SoftPLCError(f"{path}: over {MAX_CEX_BYTES // 2**20} MiB, not a "
                               "counterexample file")
        data = json.loads(Path(path).read_text(), parse_constant=_finite)
    except (OSError, ValueError, RecursionError) as e:
        raise SoftPLCError(f"{path}: not a counterexample file ({e})") from None
    if not isinstance(data, dict) or data.get("format") != CEX_FORMAT:
        raise SoftPLCError(f"{path}: not a counterexample file written by softplc verify "
                           f"--cex")
    _check_cex(path, data.get("counterexamples"))
    return data


def replay_hook(plc: Any, cex: dict[str, Any]) -> Callable[[], None]:
    """A `before_scan` hook applying the counterexample's inputs of scan n (counted from
    the cold start, so stepping back in the debugger replays the same inputs)."""
    scans = [row["inputs"] for row in cex["scans"]]

    def hook() -> None:
        n = plc.scan_count
        if n < len(scans):
            set_inputs(plc, scans[n])
    return hook


def emit_test(path: Path, program: Path, config: Path | None,
              items: list[dict[str, Any]], symbols: Any = None) -> None:
    """A pytest file: each counterexample's inputs replayed in the engine, asserting the
    requirement holds, so it fails until the program is fixed; a comment names the
    inputs' symbols (`symbols`: the configuration's SymbolTable)."""
    def rel(p: Path) -> str:  # from the test's folder: the test runs from anywhere
        return os.path.relpath(Path(p).resolve(), Path(path).resolve().parent)

    lines = ['"""Counterexamples found by `softplc verify`: each test replays the inputs',
             'scan by scan from a cold start and fails while the requirement is broken."""',
             "", "from pathlib import Path", "",
             "from softplc.plc import PLC", "from softplc.verify.replay import first_failure",
             "", "HERE = Path(__file__).parent", f"PROGRAM = HERE / {rel(program)!r}",
             f"CONFIG = HERE / {rel(config)!r}" if config else "CONFIG = None", ""]
    for i, it in enumerate(items):
        scans = [row["inputs"] for row in it["scans"]]
        named = [symbols.label(k) for k in dict.fromkeys(k for row in scans for k in row)
                 ] if symbols is not None else []
        lines += ["", f"def test_requirement_{i}():",
                  f"    # {it['requirement']}",
                  *([f"    # inputs: {' '.join(named)}"] if any("(" in n for n in named)
                    else []),
                  f"    check = {it['check']!r}",
                  f"    scans = {scans!r}",
                  "    with PLC.from_file(PROGRAM, CONFIG, devices=False) as plc:",
                  "        failed = first_failure(plc, check, scans)",
                  "    assert failed is None, f'{check} broken at scan {failed}'", ""]
    path.write_text("\n".join(lines))
