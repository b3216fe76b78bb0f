"""The function blocks of a machine, built from the configuration by the catalog
(`softplc/twido/catalog.py`): each family's section is handed to its set-up hook (in the
family's module: `softplc/blocks/` for the basic ones), then each distinct `finish` hook
attaches what runs at scan time; a block the program uses but the configuration does not
name gets its family's default, or a message saying what to configure.

    setup = BlockSetup(mem, profile, time_source, scan_period, engine, symbols)
    setup.configure(settings)           # every block section of a `config.Config`
    setup.factory(ref)                  # the program uses `ref`: None, or what is wrong
"""

from __future__ import annotations

from typing import Any

from softplc.config import key_path
from softplc.config.models import _bit, _word
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue, located
from softplc.twido import catalog
from softplc.twido.address import Ref, parse_address
from softplc.twido.catalog import Family
from softplc.twido.symbols import SymbolTable


class BlockSetup:
    """What a family's set-up needs (the memory image, profile, time source, scan period,
    engine) and what set-ups share: the base's claimed inputs and outputs (%I0.x / %Q0.x
    channel -> what uses it) and `shared` objects (the pulse outputs, the counting hub)."""

    def __init__(self, mem: Any, profile: Any, time_source: Any, scan_period: float,
                 engine: Any = None, symbols: SymbolTable | None = None):
        self.mem, self.profile, self.time_source = mem, profile, time_source
        self.scan_period, self.engine = scan_period, engine
        self.symbols = symbols  # the names an address of a section may be given by
        self.inputs: dict[int, str] = {}
        self.outputs: dict[int, str] = {}
        self.shared: dict[str, Any] = {}

    # ---- building ----------------------------------------------------------------------------
    def configure(self, settings: Any, online: bool = False,
                  symbols: SymbolTable | None = None) -> None:
        """Create the blocks `settings` configures, family by family in catalog order, then
        run the finish hooks; `online`: only the sections an online change may alter
        (replacing the blocks of the same address); `symbols`: the table of `settings`,
        when it replaces the one the set-up was made with. One ConfigError with every
        family's problems, each at its key path (the finish hooks run when there is none)."""
        if symbols is not None:
            self.symbols = symbols
        finish: list[str] = []
        issues: list[ConfigIssue] = []
        for fam in catalog.FAMILIES.values():
            if not fam.setup or (online and not fam.online):
                continue
            entries = getattr(settings, fam.section)
            if entries:
                try:
                    catalog.resolve(fam.setup)(self, fam, entries)
                except ConfigError as e:  # a hook stops at its first: the next family's
                    issues += [located(i, fam.section) for i in e.issues]
            if fam.finish and fam.finish not in finish:
                finish.append(fam.finish)
        if issues:
            raise ConfigError(issues)
        for hook in finish:
            catalog.resolve(hook)(self)

    def factory(self, ref: Ref) -> str | None:
        """Create a block the program uses but the configuration does not name, where
        Twido has an obvious default; otherwise say what to configure."""
        count = self.profile.count(ref.kind)
        if ref.index >= count:
            return f"{ref} beyond the {count} %{ref.kind} of {self.profile.name}"
        blocks = self.mem.blocks[ref.kind]
        if ref.index not in blocks:
            fam = catalog.family(ref.kind)
            if fam.unconfigured:
                q = self.profile.pulse_outputs[ref.index] if fam.pulse_output else None
                return fam.unconfigured.format(ref=ref, section=fam.section, title=fam.title,
                                               q=q)
            blocks[ref.index] = catalog.resolve(fam.default)(self.profile) if fam.default \
                else fam.block_class()
        return None

    # ---- what the set-ups share ------------------------------------------------------------
    @staticmethod
    def where(section: str, key: str) -> str:
        return key_path((section, key))

    def block_ref(self, text: str, fam: Family, noun: str = "object") -> Ref:
        """The block a configuration key names, of the family of its section."""
        where = self.where(fam.section, text)
        try:
            ref = parse_address(text, self.profile)
        except AddressError as e:
            raise ConfigError(ConfigIssue(where, str(e), ConfigCode.ADDRESS)) from None
        if ref.kind != fam.kind or not ref.is_block:
            raise ConfigError(ConfigIssue(where, f"{text!r} is not a %{fam.kind} {noun}",
                                          ConfigCode.ADDRESS))
        return ref

    def word(self, where: str, key: str, v: Any, writable: bool = False) -> Any:
        """A constant stays an int; an address must be a single 16-bit word."""
        return _word(where, key, v, self.mem, writable)

    def bit(self, where: str, key: str, v: Any, kinds: tuple[str, ...]) -> Ref | None:
        return _bit(where, key, v, self.mem, kinds)

    def each(self, fam: Family, entries: dict[str, Any], make: Any) -> None:
        """Each entry's block, made by `make(options, key)`, into the family's blocks; every
        entry's problems raised together (a set-up hook's common loop)."""
        issues: list[ConfigIssue] = []
        for text, o in entries.items():
            try:
                ref = self.block_ref(text, fam)
                self.mem.blocks[fam.kind][ref.index] = make(o, text)
            except ValueError as e:
                issues.append(ConfigIssue(self.where(fam.section, text), str(e),
                                          ConfigCode.VALUE))
            except ConfigError as e:
                issues += e.issues
        if issues:
            raise ConfigError(issues)

    def claim_input(self, channel: int, who: str) -> int:
        """%I0.`channel` for `who` alone (a counting input); its flat index."""
        if channel in self.inputs:
            raise ConfigError(f"{who}: input %I0.{channel} is already {self.inputs[channel]}")
        self.inputs[channel] = who
        self.mem.use_io(parse_address(f"%I0.{channel}", self.profile))
        return channel  # base inputs: flat index = channel
