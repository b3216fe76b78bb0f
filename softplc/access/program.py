"""The running program through the access port: what runs (file, hash, version), its
listing and symbols, its Modbus map, and an online change checked off the scan thread and
swapped at a scan boundary (`softplc.online`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from softplc import assembly as build
from softplc import online
from softplc.persist.retain import application_id
from softplc.twido.symbols import SymbolTable


def _anchored(raw: dict[str, Any], base: Path | None) -> dict[str, Any]:
    """`raw` with a relative `symbols_file` made absolute from `base` (the folder of the
    running configuration): a configuration given as text or dict has no folder of its
    own."""
    file = raw.get("symbols_file")
    if base is not None and isinstance(file, str) and file and not Path(file).is_absolute():
        return raw | {"symbols_file": str(base / file)}
    return raw


class ProgramAccess:
    def __init__(self, plc: Any, image: Any = None):
        self.plc = plc
        self.image = image  # the Modbus image: its state file follows a program change
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

    def plan(self, text: str, raw: dict[str, Any] | None,
             name: str) -> tuple[online.Plan, SymbolTable]:
        """Check and compile `text` against `raw` (None: the running configuration) in any
        thread but the scan's: the plan and the symbols of its configuration."""
        plc = self.plc
        config = _anchored(dict(plc.config if raw is None else raw), plc.config_dir)
        change = online.plan(plc, text, config, file=name)
        return change, change.symbols

    def app_id(self, text: str, raw: dict[str, Any] | None) -> bytes:
        """What `softplc run` would call this application (the configuration as written,
        not anchored): a restart with the new program finds its state file its own."""
        if raw is None:
            return build.application_id(self.plc.machine, text.encode())
        return application_id(text.encode(), raw)

    def swap(self, plan: online.Plan, names: SymbolTable, version: int, *, confirm: bool,
             cold: bool, app: bytes) -> dict[str, Any]:
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
            store.app = app  # with it warm-starts, with the old one not
        return self.info()


__all__ = ["ProgramAccess"]
