"""Reading and writing the estimator's files: every failure a `MassFileError` naming the
file; writes are all or nothing."""

from __future__ import annotations

import os
from pathlib import Path

from softplc.errors import MassFileError


def read_text(path: str | Path, what: str) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise MassFileError(f"{path}: cannot read the {what} ({e})") from e


def read_bytes(path: str | Path, what: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise MassFileError(f"{path}: cannot read the {what} ({e.strerror})") from e


def write_atomic(path: str | Path, data: bytes) -> None:
    """Write a whole file or nothing (temporary file, then rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise MassFileError(f"{path}: cannot write ({e.strerror})") from e
