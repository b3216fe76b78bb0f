"""Input limits every parser applies, and the checks they share.

Each reader (IL programs, configurations, symbol CSVs, requirement files, state files, the
web JSON API, G-code, DXF) bounds what it takes: the digits of a number, its range, the
nesting depth, the file size and the element count. A value past a limit is refused with a
`BoundsError` carrying its line:col, which the reader turns into its own coded error
(`ParseError`, `ConfigError`, `VerifyError`, ...): never a traceback, never Python's own
limits (4,300 digits for `int()`, the recursion limit) or a MemoryError.

The limits and their reasons are listed in docs/reliability.md.
"""

from __future__ import annotations

import errno
import math
import os
import re
import stat
import time
from pathlib import Path

from softplc.errors import SoftPLCError

#: Digits (and letters of a hex constant) in one numeric literal. A Twido value has at most
#: 10 digits (a 32-bit %MD), and 17 significant digits round-trip any double; 100 leaves
#: room for zero-padded or over-precise exports while keeping every conversion cheap and
#: far below Python's 4,300-digit `int()` limit.
MAX_NUMBER_DIGITS = 100
#: Nesting of brackets in a TOML file (arrays, inline tables). The deepest a softplc file
#: uses is 3 (`[devices.x]` with an inline table of arrays); tomllib recurses per level and
#: hits Python's recursion limit near 1,000.
MAX_TOML_DEPTH = 32
#: Nesting of parentheses and NOT in a requirement expression, as MAX_EXPR_DEPTH for an IL
#: operation block (softplc.il.parser): the parser recurses per level.
MAX_EXPR_NESTING = 64
#: Largest text file a reader takes, in bytes, by kind. A Twido program is at most a few
#: thousand instructions (under 1 MB of text; the benchmarks parse 1 MB programs) and its
#: configuration, symbols and requirements far less; DXF drawings are the largest input
#: (200,000 LINEs are about 23 MB).
MAX_PROGRAM_BYTES = 16 * 1024 * 1024
MAX_CONFIG_BYTES = 1024 * 1024
MAX_SYMBOLS_BYTES = 4 * 1024 * 1024
MAX_REQUIREMENTS_BYTES = 1024 * 1024
MAX_GCODE_BYTES = 64 * 1024 * 1024
MAX_DXF_BYTES = 256 * 1024 * 1024


class BoundsError(SoftPLCError):
    """An input past one of the limits above: `message` at `line`:`col` (1-based; 0 when
    the whole input is meant)."""

    def __init__(self, message: str, line: int = 0, col: int = 0):
        self.message, self.line, self.col = message, line, col
        where = f"{line}:{col}: " if line else ""
        super().__init__(where + message)


def check_digits(text: str, line: int = 0, col: int = 0) -> None:
    """Refuse a numeric literal longer than MAX_NUMBER_DIGITS characters."""
    if len(text) > MAX_NUMBER_DIGITS:
        raise BoundsError(f"a number of {len(text)} characters (at most {MAX_NUMBER_DIGITS})",
                          line, col)


def finite(value: float, what: str, line: int = 0, col: int = 0) -> float:
    """`value` if it is a finite number; BoundsError for NaN and the infinities."""
    if not math.isfinite(value):
        raise BoundsError(f"{what} is {value}: a finite number is expected", line, col)
    return value


def position(text: str, offset: int) -> tuple[int, int]:
    """1-based (line, col) of a character offset."""
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def read_bytes(path: str | Path, limit: int, what: str) -> bytes:
    """The content of a file the operator named (a pipe such as /dev/stdin too), of at most
    `limit` bytes (read no further: /dev/zero or a huge file cannot fill the memory).
    OSError is left to the caller. A file someone else named: `read_regular`."""
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise BoundsError(f"{what} is larger than {limit // 1024} KiB")
    return data


def decode_text(data: bytes, what: str, fallback: str | None = None) -> str:
    """UTF-8 text (a BOM dropped), or `fallback` (e.g. "cp1252") if it is not UTF-8. A file
    with a NUL byte, or undecodable either way, is binary: BoundsError at its line:col."""
    nul = data.find(b"\0")
    if nul >= 0:
        line, col = position(data.decode("latin-1"), nul)
        raise BoundsError(f"{what} is not a text file (a NUL byte: binary)", line, col)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        bad = e.start + (3 if data.startswith(b"\xef\xbb\xbf") else 0)
    if fallback is not None:
        try:
            return data.decode(fallback)
        except UnicodeDecodeError as e:
            bad = e.start
    line, col = position(data.decode("latin-1"), bad)
    raise BoundsError(f"{what} is not a text file: byte 0x{data[bad]:02x} is no character of "
                      f"{'UTF-8' + (' or ' + fallback if fallback else '')}", line, col)


# A TOML string (basic, literal, multi-line) or comment: skipped by `check_toml`.
_TOML_SKIP = re.compile(r'"""(?:[^\\]|\\.)*?"""|\'\'\'.*?\'\'\'|"(?:[^"\\\n]|\\.)*"|'
                        r"'[^'\n]*'|#[^\n]*", re.S)
_TOML_SCAN = re.compile(r'"""|\'\'\'|"|\'|#|[\[\]{}]|[0-9][0-9_]*')


def check_toml(text: str) -> None:
    """Refuse, before tomllib reads it, a TOML text nested deeper than MAX_TOML_DEPTH or
    with a number longer than MAX_NUMBER_DIGITS (tomllib recurses per level and calls
    `int()` on any run of digits): BoundsError at the line:col of the first."""
    depth, pos = 0, 0
    while True:
        m = _TOML_SCAN.search(text, pos)
        if m is None:
            return
        tok = m.group()
        if tok[0] in "\"'#":
            skip = _TOML_SKIP.match(text, m.start())
            pos = skip.end() if skip else len(text)  # an unclosed string: tomllib's error
            continue
        pos = m.end()
        if tok in "[{":
            depth += 1
            if depth > MAX_TOML_DEPTH:
                raise BoundsError(f"nested more than {MAX_TOML_DEPTH} levels deep",
                                  *position(text, m.start()))
        elif tok in "]}":
            depth = max(depth - 1, 0)
        else:
            check_digits(tok.replace("_", ""), *position(text, m.start()))


# ---- a file that someone else named (an online change, a kept program) ----------------
# Opened without blocking (a FIFO, a device or a socket is refused, never waited on), a
# regular file only, its size capped before it is read (and while reading: a file that
# grows is cut off), read within a deadline. Errors say what is wrong with the file, never
# what is in it.
READ_CHUNK = 64 * 1024  # bytes read at a time between two deadline checks


class FileRefused(SoftPLCError):
    """The file cannot be read: `refused` True when it is one that may not be read (a
    link, not a regular file, too large, too slow), False when it cannot be (absent,
    permissions, I/O error)."""

    def __init__(self, message: str, refused: bool):
        super().__init__(message)
        self.refused = refused


def read_regular(path: Path, what: str, limit: int, deadline_s: float,
                 follow: bool = True) -> bytes:
    """The bytes of the regular file `path` (at most `limit`, within `deadline_s` s).
    `follow`: False refuses a symbolic link as the last component. FileRefused else."""
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow else os.O_NOFOLLOW)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise FileRefused(f"{path}: no such {what}", False) from None
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise FileRefused(f"{path}: a symbolic link, refused", True) from None
        raise FileRefused(f"{path}: cannot read the {what}: {e.strerror or e}", False) \
            from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise FileRefused(f"{path}: not a regular file (a FIFO, a device, a folder or a "
                              f"socket), refused", True)
        if st.st_size > limit:
            raise FileRefused(f"{path}: {st.st_size} bytes, over the {limit} a {what} may "
                              f"have", True)
        end = time.monotonic() + deadline_s
        parts: list[bytes] = []
        size = 0
        while chunk := os.read(fd, READ_CHUNK):
            size += len(chunk)
            if size > limit:
                raise FileRefused(f"{path}: grew past the {limit} bytes a {what} may have",
                                  True)
            if time.monotonic() > end:
                raise FileRefused(f"{path}: not read within {deadline_s:g} s", True)
            parts.append(chunk)
        return b"".join(parts)
    except OSError as e:
        raise FileRefused(f"{path}: cannot read the {what}: {e.strerror or e}", False) \
            from None
    finally:
        os.close(fd)
