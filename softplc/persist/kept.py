"""The program a state file's data belongs to, kept beside it: `STATE.program`.

A Twido keeps the application last downloaded into it with its data: power restored
without program loss is a warm restart (program and data held in battery-backed RAM, the
program also backed up in the internal EEPROM); a cold start comes with a new application
downloaded, a lost program or %S0 (industrialmonitordirect.com, "Twido TWDLCAA24DRF cold
start vs warm start conditions"; control.com thread 17899 on the %SW96 EEPROM backup;
docs/twido.md#scan-cycle on %S1). A soft Twido's
online change (`softplc load`, POST /api/program) is that download: the program, its
configuration and the files it named (the symbols) are written here before the swap, so
that a restart with the original command line (what a supervisor does after kill -9) finds
the program its data belongs to (`softplc.daemon`, docs/online-change.md).

The file holds up to two records (JSON): the program about to run and the one running
before it, each tagged with its application id (`retain.application_id`, which the state
file's slots carry). The state file says which application its data belongs to; the
record with that id is the program to run. A swap cut off between the two writes leaves
the state file naming the old id, whose record is still here. Written atomically (a new
file renamed over the old one, fsync'ed); read size-capped (`softplc.limits.read_regular`).
"""

from __future__ import annotations

import base64
import json
import logging
import os
import time
from dataclasses import dataclass, field
from datetime import date, datetime
from datetime import time as dtime
from pathlib import Path
from typing import Any

from softplc.limits import FileRefused, read_regular
from softplc.persist.retain import StateFileError, _fsync_dir

log = logging.getLogger("softplc.retain")

SUFFIX = ".program"
FORMAT = 1
#: The largest kept-program file: two records of a program of up to 4 MiB (the web API's
#: body limit, softplc.web.program.MAX_PROGRAM_BODY) and its files, base64-encoded.
MAX_KEPT_BYTES = 48 * 1024 * 1024
READ_DEADLINE_S = 10.0  # a 48 MiB file on a slow card; a normal one reads in milliseconds
RECORDS = 2  # the program about to run and the one running before it


def path_of(state: Path) -> Path:
    """Where the program of the state file `state` is kept."""
    return state.with_name(state.name + SUFFIX)


@dataclass
class KeptProgram:
    """One program as it runs: its IL text and file name, its configuration as written,
    the files that configuration named (as read), when it was loaded, its version
    (online changes so far), its application id (`app`) and that of the command-line
    program the daemon started from before any online change (`origin`)."""

    app: bytes
    origin: bytes
    file: str
    source: str
    config: dict[str, Any]
    files: dict[str, bytes] = field(default_factory=dict)
    version: int = 0
    loaded_at: float = 0.0

    @property
    def changed_online(self) -> bool:
        return self.app != self.origin

    def describe(self) -> str:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.loaded_at))
        how = f"online change {self.version}" if self.changed_online else "started"
        return f"{self.file} ({how}, loaded {when}, application {self.app.hex()[:12]})"

    def as_json(self) -> dict[str, Any]:
        return {"app": self.app.hex(), "origin": self.origin.hex(), "file": self.file,
                "source": self.source, "config": _tagged(self.config),
                "files": {k: base64.b64encode(v).decode() for k, v in self.files.items()},
                "version": self.version, "loaded_at": self.loaded_at}

    @classmethod
    def of_json(cls, d: dict[str, Any]) -> KeptProgram:
        return cls(bytes.fromhex(d["app"]), bytes.fromhex(d["origin"]), str(d["file"]),
                   str(d["source"]), _untagged(d["config"]),
                   {str(k): base64.b64decode(v) for k, v in d["files"].items()},
                   int(d["version"]), float(d["loaded_at"]))


_TAGS = {"$datetime": datetime.fromisoformat, "$date": date.fromisoformat,
         "$time": dtime.fromisoformat}


def _tagged(v: Any) -> Any:
    """A TOML value as JSON: its dates and times tagged."""
    if isinstance(v, dict):
        return {k: _tagged(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_tagged(x) for x in v]
    if isinstance(v, datetime):
        return {"$datetime": v.isoformat()}
    if isinstance(v, date):
        return {"$date": v.isoformat()}
    if isinstance(v, dtime):
        return {"$time": v.isoformat()}
    return v


def _untagged(v: Any) -> Any:
    if isinstance(v, dict):
        if len(v) == 1 and next(iter(v)) in _TAGS:
            tag, text = next(iter(v.items()))
            return _TAGS[tag](text)
        return {k: _untagged(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_untagged(x) for x in v]
    return v


class ProgramKeeper:
    """The kept programs of one state file: `find` the one an application id names,
    `keep` a new one (written before it runs), `running` the one that runs now."""

    def __init__(self, state: Path):
        self.path = path_of(state)
        self.records: list[KeptProgram] = self._read()
        self.running: KeptProgram | None = None

    def _read(self) -> list[KeptProgram]:
        try:
            data = read_regular(self.path, "kept program", MAX_KEPT_BYTES, READ_DEADLINE_S,
                                follow=False)
        except FileRefused as e:
            if e.refused or self.path.exists():
                log.warning("%s", e)  # then no program is kept: the daemon says what it does
            return []
        try:
            d = json.loads(data)
            if d.get("format") != FORMAT:
                raise ValueError(f"format {d.get('format')!r}, not {FORMAT}")
            return [KeptProgram.of_json(r) for r in d["programs"]][:RECORDS]
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            log.warning("%s: unreadable (%s): no program kept", self.path, e)
            return []

    def find(self, app: bytes) -> KeptProgram | None:
        return next((r for r in self.records if r.app == app), None)

    def keep(self, record: KeptProgram) -> None:
        """Write `record` with the running one (the state file names either until the swap
        is made). StateFileError if it cannot be written: then the change is not made."""
        records = [record] + [r for r in (self.running,) if r is not None and r.app != record.app]
        if [r.app for r in records] == [r.app for r in self.records]:
            return  # kept already (a restart of the program kept)
        body = json.dumps({"format": FORMAT, "programs": [r.as_json() for r in records]})
        tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW
                         | os.O_CLOEXEC, 0o600)
            try:
                data = memoryview(body.encode())
                while data:
                    data = data[os.write(fd, data):]
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(tmp, self.path)
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise StateFileError(f"cannot keep the program beside the state file "
                                 f"({self.path}): {e.strerror or e}") from None
        _fsync_dir(self.path.parent)
        self.records = records


__all__ = ["KeptProgram", "ProgramKeeper", "path_of"]
