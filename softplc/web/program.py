"""The running program over the web API: its listing and version, an online change
(`POST /api/program`) and the Modbus map (`GET /api/map`).

An online change is checked and compiled (`online.plan`) in a worker thread, never in the
event loop (a 1 MB program takes seconds) nor in the scan thread; the swap itself
(`online.apply`) is queued in the control lane of the change queue and runs in the scan
thread between two scans. One change at a time: a second one while the first is checked
is refused (409). A plan made against another program version than the one running when
the swap comes (two pages loading at once) is refused too: nothing changes.

The configuration sent names no file of the host: the files it names come with the
request (`"files": {"name.csv": "text"}`), or from the running configuration, or from under
the daemon's --config-dir (`softplc.config.files.Carried`).

The answer says what happened, always: a swap the scan thread has not begun when the
deadline passes is withdrawn (it never runs: "not changed", 503); one it has begun is
waited for and reported as it ended; one still running after a second deadline is
answered 202 `"applied": null` with the version to look for (GET /api/program).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
from dataclasses import asdict
from typing import Any

from softplc import online
from softplc.access.program import ProgramAccess
from softplc.config import parse_toml
from softplc.config.files import carried_files
from softplc.errors import ConfigError, ProgramError, SoftPLCError
from softplc.modbus import tags
from softplc.modbus.regmap import COILS
from softplc.twido.symbols import SymbolTable
from softplc.web.control import Controller
from softplc.web.errors import ApiError

MAX_PROGRAM_BODY = 4 * 1024 * 1024  # POST /api/program: a ~1 MB program, JSON-escaped
APPLY_TIMEOUT = 10.0  # s waiting for the scan thread to make the swap
MAX_ERRORS = 200  # diagnostics listed in one answer
#: What the map page says of the objects it lists apart.
HIDDEN_NOTE = ("A Twido exposes only %M bits (coils) and %MW/%MD/%MF words (holding "
               "registers) over Modbus: inputs (%I), outputs (%Q), timers (%TM), counters "
               "and other blocks, system bits and words are not on the map. A program "
               "copies what a host needs to %M/%MW.")


def diagnostics(e: ProgramError) -> list[dict[str, Any]]:
    return [{"line": d.line, "column": d.column, "message": d.message, "text": d.text,
             "expected": d.expected, "error": str(d)} for d in e.diagnostics[:MAX_ERRORS]]


class ProgramChanges:
    """The program routes' job over a `Controller` (its access port's program, queue and
    objects)."""

    def __init__(self, controller: Controller):
        self.ctl = controller
        self.program: ProgramAccess = controller.port.program
        self._busy = False  # a change is being checked or applied

    # -- reading -----------------------------------------------------------------------------
    def listing(self) -> dict[str, Any]:
        return self.program.listing()

    def program_map(self) -> tags.ProgramMap:
        return self.program.modbus_map()

    def map_json(self) -> dict[str, Any]:
        pmap = self.program_map()
        rows = []
        for t in pmap.tags:
            row = asdict(t) | {"table": "coil" if t.space == COILS else "holding register",
                               "reference": t.reference, "read_fc": list(t.read_fcs),
                               "write_fc": list(t.write_fcs)}
            del row["space"]
            rows.append(row)
        return {"info": self.program.info(), "tags": rows,
                "hidden": [asdict(h) for h in pmap.hidden], "note": HIDDEN_NOTE}

    def map_csv(self) -> str:
        return tags.to_csv(self.program_map())

    # -- changing ----------------------------------------------------------------------------
    @staticmethod
    def _request(data: dict[str, Any]) -> tuple[str, dict[str, Any] | None, str, bool, bool,
                                                dict[str, bytes]]:
        text, config = data.get("program"), data.get("config")
        if not isinstance(text, str) or not text.strip():
            raise ApiError('"program": the IL text of the new program')
        if config is not None and not isinstance(config, str):
            raise ApiError('"config": the TOML text of the configuration, or null to keep '
                           'the running one')
        name = data.get("file", "<online change>")
        if not isinstance(name, str) or len(name) > 200:
            raise ApiError('"file": the program\'s file name (for the messages)')
        flags = []
        for key in ("confirm", "cold"):
            v = data.get(key, False)
            if not isinstance(v, bool):
                raise ApiError(f'"{key}": true or false, not {v!r}')
            flags.append(v)
        raw = None
        if config is not None:
            try:
                raw = parse_toml(config)
            except ConfigError as e:
                raise ApiError(f"configuration: {e}") from None
        try:
            files = carried_files(data.get("files"))
        except ConfigError as e:
            raise ApiError(f'"files": the files the configuration names, {e}') from None
        return text, raw, name or "<online change>", flags[0], flags[1], files

    async def change(self, data: dict[str, Any]) -> tuple[int, dict[str, Any]]:
        """Check, then apply if nothing is lost or the change is confirmed: (status, body)."""
        if self.ctl.read_only:
            raise ApiError("the web monitor is read-only (--web-read-only)", 403)
        text, raw, name, confirm, cold, files = self._request(data)
        if self._busy:
            raise ApiError("another program change is being made: try again when it is "
                           "done", 409)
        self._busy = True
        try:
            program = self.program
            version = program.version
            loop = asyncio.get_running_loop()
            try:
                plan, names = await loop.run_in_executor(None, program.plan, text, raw, name,
                                                         files)
            except ProgramError as e:
                errors = diagnostics(e)
                return 400, {"error": f"the program was not loaded: {len(e.diagnostics)} "
                             f"error(s), nothing changed\n"
                             + "\n".join(d["error"] for d in errors),
                             "errors": errors, "applied": False}
            except (ConfigError, online.ChangeRefused) as e:
                return 400, {"error": f"not loaded, nothing changed: {e}", "errors": [],
                             "applied": False}
            if plan.needs_confirmation and not (confirm or cold):
                return 200, {"applied": False, "losses": plan.losses,
                             "needs_confirmation": True, "info": program.info()}
            app = program.app_id(text, raw)
            try:  # kept with the state file before it runs: a restart runs it too
                kept = await loop.run_in_executor(None, program.keep, plan, text, name, app)
            except SoftPLCError as e:
                return 500, {"error": f"not loaded, nothing changed: {e}", "errors": [],
                             "applied": False}
            info = await self._swap(plan, names, version, confirm, cold, app, kept)
            self.ctl.objects.forget()
            if info is None:  # still being made: say so, and what to look for
                return 202, {"applied": None, "pending": True, "version": version + 1,
                             "error": f"the swap is being made by the scan thread: GET "
                                      f"/api/program shows version {version + 1} once it is "
                                      f"done", "info": program.info()}
            return 200, {"applied": True, "losses": plan.losses, "cold": cold, "info": info}
        finally:
            self._busy = False

    async def _swap(self, plan: online.Plan, names: SymbolTable, version: int,
                    confirm: bool, cold: bool, app: bytes,
                    kept: Any = None) -> dict[str, Any] | None:
        """Queue the swap in the control lane; wait for the scan thread to make it: what
        runs then, or None if it is still being made after two deadlines."""
        done: concurrent.futures.Future[dict[str, Any]] = concurrent.futures.Future()

        def swap() -> None:  # the scan thread, between two scans
            if not done.set_running_or_notify_cancel():
                return  # withdrawn at the deadline: it was answered "not changed"
            try:
                done.set_result(self.program.swap(plan, names, version, confirm=confirm,
                                                  cold=cold, app=app, kept=kept))
            except SoftPLCError as e:
                done.set_exception(e)
            except BaseException as e:  # the answer must not wait for nothing
                done.set_exception(e)
                raise

        self.ctl.port.call(swap)
        waiting = asyncio.wrap_future(done)
        finished, _ = await asyncio.wait({waiting}, timeout=APPLY_TIMEOUT)
        # cancel() succeeds only while the scan thread has not begun the swap: then it
        # never runs and "not changed" is true; once begun, the swap's end is the answer
        if not finished and done.cancel():
            raise ApiError(f"the scan did not reach a boundary within {APPLY_TIMEOUT:g} s: "
                           f"the program was not changed", 503)
        if not finished:
            finished, _ = await asyncio.wait({waiting}, timeout=APPLY_TIMEOUT)
            if not finished:
                return None
        try:
            return waiting.result()
        except SoftPLCError as e:
            raise ApiError(f"not loaded, nothing changed: {e}", 409) from None


__all__ = ["HIDDEN_NOTE", "MAX_PROGRAM_BODY", "ProgramChanges"]
