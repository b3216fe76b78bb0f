"""The running program through the access port: what runs (file, hash, version), its
listing and symbols, its Modbus map, and an online change checked off the scan thread and
swapped at a scan boundary (`softplc.online`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from softplc import assembly as build
from softplc import online
from softplc.config.files import Carried
from softplc.persist.kept import KeptProgram, ProgramKeeper
from softplc.persist.retain import application_id
from softplc.twido.symbols import SymbolTable


class ProgramAccess:
    def __init__(self, plc: Any, image: Any = None, files_root: Path | None = None):
        self.plc = plc
        self.image = image  # the Modbus image: its state file follows a program change
        # the folder an online change's configuration may name files in (`softplc run
        # --config-dir`); None: only the files the request carries
        self.files_root = files_root
        # the programs kept with the state file (the daemon's, with --state): an online
        # change is written there before its swap
        self.keeper: ProgramKeeper | None = None
        self._map: tuple[int, Any] | None = None

    @property
    def version(self) -> int:
        return self.plc.program_version

    def info(self) -> dict[str, Any]:
        """What runs: file, hash, time loaded, version (online changes so far)."""
        return online.ProgramInfo.of(self.plc).as_dict()

    def symbols(self) -> dict[str, list[str]]:
        """address -> [symbol, comment] of the running configuration."""
        return {s.address: [s.name, s.comment] for s in self.plc.symbols}

    def listing(self) -> dict[str, Any]:
        """The IL source and where each rung is in it."""
        plc = self.plc
        return {"info": self.info(), "source": plc.ast.source,
                "rungs": [{"index": r.index, "first_line": r.first_line,
                           "last_line": r.last_line} for r in plc.rungs]}

    def modbus_map(self) -> Any:
        """The Modbus map of the running program (`softplc.modbus.tags.ProgramMap`), kept
        until the program changes."""
        from softplc.modbus import tags  # above this package: imported when a map is asked for

        if self._map is None or self._map[0] != self.version:
            self._map = (self.version, tags.of_plc(self.plc))
        return self._map[1]

    def plan(self, text: str, raw: dict[str, Any] | None, name: str,
             files: dict[str, bytes] | None = None) -> tuple[online.Plan, SymbolTable]:
        """Check and compile `text` against `raw` (None: the running configuration) in any
        thread but the scan's: the plan and the symbols of its configuration. The
        configuration comes from the network: the files it names are those `files` carries
        (name -> bytes), those the running configuration read at its start, or regular files
        under `files_root`; no other (`softplc.config.files.Carried`)."""
        plc = self.plc
        policy = Carried(plc.machine.files.served | (files or {}), self.files_root)
        config = dict(plc.config if raw is None else raw)
        change = online.plan(plc, text, config, file=name, files=policy)
        return change, change.symbols

    def app_id(self, text: str, raw: dict[str, Any] | None) -> bytes:
        """What `softplc run` would call this application (the configuration as written,
        not anchored): a restart with the new program finds its state file its own."""
        if raw is None:
            return build.application_id(self.plc.machine, text.encode())
        return application_id(text.encode(), raw)

    def keep(self, plan: online.Plan, text: str, name: str, app: bytes) -> KeptProgram | None:
        """Before the swap (not in the scan thread): write what the change will run beside
        the state file, so that a restart runs it with its data. StateFileError if it
        cannot be written: then the change is not made."""
        if self.keeper is None:
            return None
        running = self.keeper.running
        record = online.kept_record(self.plc, app, app if running is None else running.origin,
                                    plan, name, text)
        self.keeper.keep(record)
        return record

    def swap(self, plan: online.Plan, names: SymbolTable, version: int, *, confirm: bool,
             cold: bool, app: bytes, kept: KeptProgram | None = None) -> dict[str, Any]:
        """In the scan thread, between two scans: make the change planned against
        `version`; what runs then. ChangeRefused if another change came meanwhile."""
        plc = self.plc
        if plc.program_version != version:
            raise online.ChangeRefused("the program was changed by another request "
                                       "meanwhile: check and load again")
        online.apply(plc, plan, confirm=confirm, cold=cold)
        plc.symbols = names
        store = getattr(self.image, "store", None)
        if store is not None:  # the state file now belongs to the new program: a restart
            store.app = app  # runs it (kept beside the file) with its data
            # committed now, with this boundary's data: the answer "applied" must hold
            # even if the daemon stops before this scan's end commits (a stop cuts the
            # scan short, which then commits nothing: the file named the old program)
            self.image.snapshot_boundary()
        if kept is not None and self.keeper is not None:
            self.keeper.running = kept
        return self.info()


__all__ = ["ProgramAccess"]
