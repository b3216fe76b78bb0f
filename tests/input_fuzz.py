"""Mutation fuzz targets for the file readers (issue 31): requirement files and
`--require-expr`, symbol CSVs, DXF drawings, G-code programs. Each target mutates a shipped
example with `mutate_tokens` (tokens replaced by hostile ones: huge numbers, NaN, deep
nesting, binary bytes, wrong types; inserted, deleted, repeated) and reads it: the outcome
is "read" or "refused" (the reader's own coded error); any other exception escapes and is a
traceback. tests/unit/test_input_fuzz.py runs a small budget of each (fuzz_budget.py),
`make fuzz` (tools/fuzz_mutations.py) the full one."""

from __future__ import annotations

import re
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "ladder_programs"
TOKEN = re.compile(r"%?[A-Za-z_]+[\d.:]*|\d+(\.\d+)?|\S")
BIG = "9" * 5000
# what every reader is fed, whatever its format
HOSTILE = [BIG, "1e999", "-1e999", "nan", "NaN", "inf", "-inf", "1e300", "-0", "0", "",
           "\x00", "\xff\xfe", "\r", "\n", "\t", '"', "'", "#" + "F" * 300, "((((((((",
           "NOT (" * 200, "[" * 200, "{" * 200, "\\", ",", ";", "=", "-" * 300]


def mutate_tokens(text: str, data: Any, replacements: list[str], rounds: int = 4) -> str:
    """`text` with 1..`rounds` of its tokens replaced, inserted before, deleted or
    repeated (2-40 times), new tokens drawn from `replacements` and the text's own."""
    tokens = list(TOKEN.finditer(text))
    out = text
    for _ in range(data.draw(st.integers(1, rounds))):
        m = data.draw(st.sampled_from(tokens))
        new = data.draw(st.sampled_from(replacements) | st.sampled_from(
            [t.group(0) for t in tokens]))
        kind = data.draw(st.sampled_from(["replace", "insert", "delete", "duplicate"]))
        a, b = m.span()
        if kind == "replace":
            out = out[:a] + new + out[b:]
        elif kind == "insert":
            out = out[:a] + new + " " + out[a:]
        elif kind == "delete":
            out = out[:a] + out[b:]
        else:
            out = out[:a] + out[a:b] * data.draw(st.integers(2, 40)) + out[b:]
        tokens = list(TOKEN.finditer(out)) or tokens
    return out


def _file(tmp: str, name: str, text: str, data: Any) -> Path:
    """`text` written to `tmp/name`, at times cut short or with raw bytes in it."""
    raw = text.encode("utf-8", "surrogateescape")
    how = data.draw(st.sampled_from(["as is"] * 6 + ["cut", "bytes"]))
    if how == "cut" and raw:
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    elif how == "bytes":
        at = data.draw(st.integers(0, len(raw)))
        raw = raw[:at] + data.draw(st.binary(min_size=1, max_size=40)) + raw[at:]
    path = Path(tmp) / name
    path.write_bytes(raw)
    return path


REQUIREMENTS = sorted(EXAMPLES.glob("*.req.toml"))
REQ_TOKENS = HOSTILE + ["host", "free", "assume", "scan_period", "[environment]",
                        "[[requirement]]", "check", "within", "rising", "->", "%MW0",
                        "%Q0.1", "= 5", "= []", "= {}", "scans", "ms",
                        # floats (issue 34 item 1): objects, literals in and out of range
                        "%MF10", "%KF2", "100.0", "-2.5e-3", "1e400", "3.5e38", "NAN", "INF",
                        "1." + "0" * 200, "/", "*"]


def requirements(data: Any) -> str:
    from softplc.errors import VerifyError
    from softplc.twido.profile import DEFAULT_PROFILE
    from softplc.verify.requirements import load_spec

    seed = data.draw(st.sampled_from(REQUIREMENTS))
    text = mutate_tokens(seed.read_text(), data, REQ_TOKENS)
    expr = mutate_tokens("%I0.0 rising -> NOT (%Q0.1 OR %MW0 > 3) within 5 scans", data,
                         REQ_TOKENS, rounds=2)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            load_spec(_file(tmp, "req.toml", text, data), [expr], DEFAULT_PROFILE)
        except VerifyError:
            return "refused"
    return "read"


SYMBOLS = EXAMPLES / "star_delta_symbols.csv"
CSV_TOKENS = HOSTILE + ["%I0.0", "%MW" + BIG, "START", "a" * 40, "LD", '"' + "x" * 200_000]


def symbols(data: Any) -> str:
    from softplc.errors import ConfigError
    from softplc.twido.symbols import SymbolTable, read_csv_file

    text = mutate_tokens(SYMBOLS.read_text(), data, CSV_TOKENS)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            SymbolTable(read_csv_file(_file(tmp, "symbols.csv", text, data)))
        except ConfigError:
            return "refused"
    return "read"


DXF = EXAMPLES / "pieces" / "plate.dxf"
DXF_TOKENS = HOSTILE + ["LINE", "ARC", "CIRCLE", "LWPOLYLINE", "ENDSEC", "EOF", "10", "20",
                        "40", "42", "50", "51", "0", "1e6", "-1e6", "230", "-1"]


def dxf(data: Any) -> str:
    from softplc.machines.cutting.geometry import CuttingError
    from softplc.machines.cutting.load import load_piece

    text = mutate_tokens(DXF.read_text(), data, DXF_TOKENS, rounds=3)
    tolerance = data.draw(st.sampled_from([0.01, 1e-6, 1e-12, 10.0]))
    with tempfile.TemporaryDirectory() as tmp:
        try:
            load_piece(_file(tmp, "part.dxf", text, data), tolerance=tolerance).segments()
        except CuttingError:
            return "refused"
    return "read"


GCODE = sorted((EXAMPLES / "samples").glob("*.gcode")) + sorted(
    (EXAMPLES / "pieces").glob("*.gcode"))
GCODE_TOKENS = HOSTILE + ["G0", "G1", "G2", "G3", "G4", "G17", "G18", "G20", "G91", "X",
                          "Z", "R", "I", "K", "F", "P", "N", "M30", "X" + BIG, "R1e-9"]


def gcode(data: Any) -> str:
    from softplc.errors import ConfigError, ProgramError
    from softplc.machines.cutting.geometry import CuttingError
    from softplc.machines.cutting.load import load_piece
    from softplc.machines.gcode.parser import GCodeConfig, parse_file

    seed = data.draw(st.sampled_from(GCODE))
    text = mutate_tokens(seed.read_text(), data, GCODE_TOKENS)
    with tempfile.TemporaryDirectory() as tmp:
        path = _file(tmp, "program.gcode", text, data)
        try:
            if data.draw(st.booleans()):  # the drawing table's reader, or the cutting table's
                parse_file(path, GCodeConfig(plane="XY" if "pieces" in str(seed) else "XZ"))
            else:
                load_piece(path).segments()
        except (ProgramError, ConfigError, CuttingError):
            return "refused"
    return "read"


TARGETS: dict[str, tuple[Callable[[Any], str], int]] = {  # name: (target, full count)
    "requirement files": (requirements, 1000),
    "symbol CSVs": (symbols, 1000),
    "DXF drawings": (dxf, 400),
    "G-code programs": (gcode, 2000),
}


STAR = EXAMPLES / "star_delta.il"
JSON_TOKENS = HOSTILE + ["null", "true", "1", BIG, "{}", "[]", '"program"', '"config"',
                         '"confirm"', '"cold"', ":", "[" * 5000, "1E400"]
IL_TOKENS = HOSTILE + ["LD", "ST", "%MW0", "%MF2", "1.5E40", "[ %MW0 := " + BIG + " ]",
                       "BLK", "%TM0", "JMP %L" + BIG]


def online_change(base: str, data: Any) -> str:
    """A mutated POST /api/program against a running web monitor at `base` (…/api/): a
    200 or a 4xx with a JSON error ("read", "refused"); a 5xx or an answer that is not
    JSON is an AssertionError (a traceback)."""
    import json
    import urllib.error
    import urllib.request

    body: dict[str, Any] = {"program": mutate_tokens(STAR.read_text(), data, IL_TOKENS)}
    if data.draw(st.booleans()):
        body["config"] = mutate_tokens(STAR.with_suffix(".toml").read_text(), data,
                                       HOSTILE, rounds=2)
    for key in ("confirm", "cold", "file"):
        if data.draw(st.integers(0, 3)) == 0:
            body[key] = data.draw(st.sampled_from([True, False, 1, "x" * 300, None]))
    text = json.dumps(body)
    if data.draw(st.booleans()):  # the JSON itself mutated
        text = mutate_tokens(text, data, JSON_TOKENS, rounds=2)
    req = urllib.request.Request(base + "program", data=text.encode("utf-8", "replace"),
                                 method="POST", headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            json.loads(r.read())
            return "read"
    except urllib.error.HTTPError as e:
        answer = e.read()
        assert e.code < 500, f"HTTP {e.code}: {answer[:500]!r}\nbody: {text[:2000]}"
        assert json.loads(answer)["error"], answer[:500]
        return "refused"
