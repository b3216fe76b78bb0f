"""Reading a file that someone else named, safely: `read_regular`.

Opened without blocking (a FIFO, a device or a socket is refused, never waited on), a
regular file only, its size capped before it is read (and while reading: a file that
grows is cut off), read within a deadline. Errors say what is wrong with the file, never
what is in it. The configuration's file policy (`softplc.config.files`) and the program
kept beside a state file (`softplc.persist.kept`) read through it.
"""

from __future__ import annotations

import errno
import os
import stat
import time
from pathlib import Path

from softplc.errors import SoftPLCError

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
