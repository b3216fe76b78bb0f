"""Online program change: swap the program of a running PLC at a scan boundary, keeping
memory, timers, counters and retained state wherever the objects still exist.

A TwidoSuite user changes a program without stopping the controller. Here that is two
steps:

1. `plan(plc, program, config)` checks and compiles the new program (and configuration, if
   one is given) in a trial PLC that shares nothing with the running one, and lists what
   cannot carry over: a function block the new program no longer uses (its value is
   dropped), a block whose configuration changed (it restarts from the new one), a
   configuration section that can only change with a restart (refused outright). A program
   that does not check or compile raises `ProgramError` with every diagnostic: nothing
   changes.
2. `apply(plc, plan)` makes the swap; call it between two scans (the daemon's scan thread
   does, through the web controller's queue). `%M`, `%MW`, Grafcet steps, forced objects
   and every block that carries over keep their values; `cold=True` also cold-starts.

The running code's identity (`ProgramInfo`: file, hash, time loaded, version) is what the
web monitor shows.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.config.files import Carried
from softplc.errors import SoftPLCError
from softplc.il import ast as A
from softplc.persist.kept import KeptProgram, ProgramKeeper, path_of
from softplc.persist.retain import StateFileError
from softplc.twido import catalog
from softplc.twido.address import parse_address

#: Configuration sections an online change may alter: the blocks' (applied block by block)
#: and the descriptive ones. Any other section (scan period, devices, Modbus, analog, PID,
#: EXCH...) shapes the running machine and needs a restart.
BLOCK_SECTIONS = {f.section: f.kind for f in catalog.FAMILIES.values() if f.online}
FREE_SECTIONS = {"name", "description", "symbols", "symbols_file"}


class ChangeRefused(SoftPLCError):
    """The change cannot be made online (a configuration section that needs a restart)."""


@dataclass(frozen=True)
class ProgramInfo:
    """Which program runs: its file, a hash of its text, when it was loaded, the count of
    online changes so far."""

    file: str
    sha256: str
    loaded_at: float  # time.time() of the load
    version: int = 0

    @classmethod
    def of(cls, plc: Any) -> ProgramInfo:
        """What `plc` runs now."""
        digest = hashlib.sha256(plc.ast.source.encode()).hexdigest()
        return cls(plc.ast.file, digest, plc.program_loaded_at, plc.program_version)

    def as_dict(self) -> dict[str, Any]:
        return {"file": self.file, "sha256": self.sha256, "hash": self.sha256[:12],
                "loaded_at": time.strftime("%Y-%m-%dT%H:%M:%S", time.localtime(self.loaded_at)),
                "version": self.version}


@dataclass
class Plan:
    """A checked change, ready to apply."""

    program: A.Program
    settings: Any  # the new `Config`
    raw_config: dict[str, Any]
    symbols: Any = None  # the new configuration's `SymbolTable`
    files: dict[str, bytes] = field(default_factory=dict)  # the files it named, as read
    losses: list[str] = field(default_factory=list)  # what does not carry over, for humans
    reset: set[tuple[str, int]] = field(default_factory=set)  # blocks (kind, index) rebuilt
    removed: set[tuple[str, int]] = field(default_factory=set)  # blocks no longer used

    @property
    def needs_confirmation(self) -> bool:
        return bool(self.losses)


def _block_configs(settings: Any) -> dict[tuple[str, int], Any]:
    """(kind, index) -> configured options of each block the configuration names."""
    out: dict[tuple[str, int], Any] = {}
    for section, kind in BLOCK_SECTIONS.items():
        for text, options in getattr(settings, section).items():
            try:
                ref = parse_address(text)
            except SoftPLCError:
                continue  # the trial PLC reported it already
            out[kind, ref.index] = options.model_dump()
    return out


def _restart_sections(old: Any, new: Any) -> list[str]:
    before, after = old.model_dump(), new.model_dump()
    return sorted(k for k in before.keys() | after.keys()
                  if k not in BLOCK_SECTIONS and k not in FREE_SECTIONS
                  and before.get(k) != after.get(k))


def _describe(options: Any) -> str:
    return ", ".join(f"{k} {v}" for k, v in options.items()) if options else "defaults"


def plan(plc: Any, program: A.Program | str | Path,
         config: str | Path | dict[str, Any] | None = None, *,
         file: str = "<online change>", files: Any = None) -> Plan:
    """Check and compile `program` (an AST, IL text or a file) against `config` (default:
    the running configuration) without touching `plc`; what will not carry over. `file`:
    the name IL text goes by in the messages; `files`: where the files the configuration
    names may come from (`softplc.config.files.FilePolicy`; None: anywhere, the caller's
    own configuration)."""
    from softplc import assembly as build
    from softplc.plc import PLC

    if config is None:
        config = plc.config
    config = build.load(config, files)
    # raises ProgramError (every syntax and semantic error, with line:col) / ConfigError
    if isinstance(program, Path):
        trial = PLC.from_file(program, config, devices=False)
    elif isinstance(program, str):
        trial = PLC.from_source(program, config, file=file, devices=False)
    else:
        trial = PLC(program, config, devices=False)
    program = trial.ast
    restart = _restart_sections(plc.settings, trial.settings)
    if restart:
        raise ChangeRefused(
            "these configuration sections cannot change while the PLC runs (restart the "
            "daemon with the new configuration): " + ", ".join(restart))
    old_cfg, new_cfg = _block_configs(plc.settings), _block_configs(trial.settings)
    result = Plan(program, trial.settings, trial.config, trial.symbols,
                  dict(trial.machine.files.served))
    running = {(k, i) for k, d in plc.mem.blocks.items() for i in d}
    kept = {(k, i) for k, d in trial.mem.blocks.items() for i in d}
    for kind, index in sorted(running - kept):
        result.removed.add((kind, index))
        result.losses.append(f"%{kind}{index} is no longer used: its value is dropped")
    for key in sorted(running & kept):
        if old_cfg.get(key) != new_cfg.get(key):
            kind, index = key
            result.reset.add(key)
            result.losses.append(
                f"%{kind}{index} configuration changed ({_describe(old_cfg.get(key))} -> "
                f"{_describe(new_cfg.get(key))}): it restarts from the new configuration")
    trial.close()
    return result


def apply(plc: Any, change: Plan, *, confirm: bool = False, cold: bool = False) -> None:
    """Swap the program (between two scans). Refuses a plan with losses unless `confirm`
    or `cold`; with `cold` the PLC also cold-starts after the swap."""
    if change.needs_confirmation and not (confirm or cold):
        raise ChangeRefused("the change loses state; confirm it or make it cold:\n  "
                            + "\n  ".join(change.losses))
    mem = plc.mem
    carried = {(k, i): b.state() for k, d in mem.blocks.items() for i, b in d.items()
               if (k, i) not in change.reset and (k, i) not in change.removed}
    old_settings, old_raw, old_symbols = plc.settings, plc.config, plc.symbols
    old_blocks = {k: dict(d) for k, d in mem.blocks.items()}
    old_cold = dict(plc.engine.cold_states)
    try:
        for kind, index in change.removed | change.reset:
            mem.blocks[kind].pop(index, None)
            plc.engine.cold_states.pop((kind, index), None)
        plc.settings, plc.config = change.settings, change.raw_config
        if change.symbols is not None:
            plc.symbols = change.symbols
        plc.block_setup.configure(change.settings, online=True,  # fresh configured blocks...
                                  symbols=plc.symbols)
        for (kind, index), st in carried.items():  # ...given back the state they carry
            block = mem.blocks.get(kind, {}).get(index)
            if block is not None:
                block.set_state(st)
        plc.replace_program(change.program)
        # the files the running configuration named, as read: the next change's (and the
        # state file's) copy, never read from disk again
        plc.machine.files = Carried.holding(change.files)
    except SoftPLCError:  # not expected after a clean plan: put the PLC back as it was
        plc.settings, plc.config, plc.symbols = old_settings, old_raw, old_symbols
        plc.block_setup.symbols = old_symbols
        for kind, blocks in mem.blocks.items():  # the old objects, with their state
            blocks.clear()
            blocks.update(old_blocks.get(kind, {}))
        plc.engine.cold_states.clear()
        plc.engine.cold_states.update(old_cold)
        raise
    if cold:
        plc.cold_start()


# -- the program kept with the retained state (softplc.persist.kept) -------------------------
#: Sections of the site, not of the application: a restored program takes the command
#: line's (retain.application_id leaves the first three out of the application).
SITE_SECTIONS = ("daemon", "modbus", "devices", "web")


def kept_record(plc: Any, app: bytes, origin: bytes, change: Plan | None = None,
                file: str | None = None, source: str | None = None) -> KeptProgram:
    """What `plc` runs (or, with `change`, what it will run: `source` from `file`) as a
    record to keep beside the state file."""
    if change is None:
        return KeptProgram(app, origin, file or plc.ast.file, plc.ast.source,
                           dict(plc.config), dict(plc.machine.files.served),
                           plc.program_version, plc.program_loaded_at)
    return KeptProgram(app, origin, file or "<online change>", source or "",
                       dict(change.raw_config), dict(change.files),
                       plc.program_version + 1, time.time())


def restore(plc: Any, kept: KeptProgram) -> None:
    """Make `plc` (built from the command line, not yet started) run the kept program:
    its text, its configuration with the command line's site sections, the files it
    named as they were read (no file is read again)."""
    config = {k: v for k, v in kept.config.items() if k not in SITE_SECTIONS} | \
        {k: v for k, v in plc.config.items() if k in SITE_SECTIONS}
    change = plan(plc, kept.source, config, file=kept.file, files=Carried.holding(kept.files))
    apply(plc, change, confirm=True)
    plc.program_version, plc.program_loaded_at = kept.version, kept.loaded_at


def _differences(kept: KeptProgram, plc: Any) -> str:
    """What differs between the kept program and the command line's, for humans."""
    out = []
    old, new = kept.source.splitlines(), plc.ast.source.splitlines()
    if old != new:
        line = next((n for n, (a, b) in enumerate(zip(old, new, strict=False), 1) if a != b),
                    min(len(old), len(new)) + 1)
        out.append(f"the program text (from line {line}; {len(old)} lines kept, "
                   f"{len(new)} in the file)")
    keys = sorted(k for k in kept.config.keys() | plc.config.keys() if k not in SITE_SECTIONS
                  and kept.config.get(k) != plc.config.get(k))
    if keys:
        out.append("the configuration (" + ", ".join(keys) + ")")
    if kept.files != dict(plc.machine.files.served):
        out.append("the files the configuration names (" + ", ".join(
            sorted(kept.files.keys() | plc.machine.files.served.keys())) + ")")
    return " and ".join(out) or "nothing visible (another softplc version's application id)"


def choose_program(plc: Any, state_app: bytes, app: bytes, keeper: ProgramKeeper, *,
                   keep_state: bool, from_state: bool, state: Path) -> tuple[bytes, str]:
    """Which program runs on a restart whose retained data belongs to application
    `state_app` when the command line's (`plc`) is `app`; makes `plc` run it and returns
    (its application id, why, for the banner). `state_app == app`: the command line's.
    Else: `keep_state` runs the command line's with the data; the kept program runs when
    `from_state` asks, or when the command line gives the program the daemon started from
    before an online change (a supervisor's restart: as a Twido, the program downloaded
    last runs); anything else raises StateFileError saying what differs, what to choose,
    and changes nothing (the state file stays as it is)."""
    if state_app == app:
        return app, "same program and configuration"
    where = f"state file {state}"
    kept = keeper.find(state_app)
    if keep_state and not from_state:
        return app, "program or configuration changed, data kept (--keep-state)"
    if kept is not None and (from_state or kept.origin == app):
        try:
            restore(plc, kept)
        except SoftPLCError as e:  # e.g. --program-from-state with another scan period
            raise StateFileError(f"{where}: the kept program {kept.describe()} cannot run "
                                 f"with this command line's configuration: {e}") from None
        reason = "--program-from-state" if from_state else (
            "the command line's program is the one it replaced; --keep-state runs the file "
            "instead, with this data")
        return kept.app, f"program kept in the state file: {kept.describe()}; {reason}"
    if from_state:
        raise StateFileError(f"{where}: --program-from-state, but no copy of the program its "
                             f"data belongs to is kept ({path_of(state)})")
    held = (f"the data of {kept.describe()};\n  the command line's {plc.ast.file} differs "
            f"in {_differences(kept, plc)}") if kept is not None else (
        f"the data of another program or configuration than {plc.ast.file} (no copy of it "
        f"is kept: saved by a softplc that kept none)")
    raise StateFileError(
        f"{where} holds {held}.\n  Nothing was started; the state file is kept as it is. "
        f"Choose:\n" + ("    --program-from-state  runs the kept program, warm, with its "
                        "data\n" if kept is not None else "")
        + f"    --keep-state          runs {plc.ast.file}, warm, with this data\n"
        f"    --cold                runs {plc.ast.file} cold (the data is discarded)")
