"""Errors users see. Bad input never reaches them as a Python traceback."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class SoftPLCError(Exception):
    """Base of every error softplc raises on purpose."""


class Code(StrEnum):
    """What kind of problem a diagnostic is: stable, whatever its message says. Tools (the
    follow-up filter of `PLC`, `check --json`) decide on the code, never on the wording."""

    SYNTAX = "syntax"  # the text does not follow the grammar
    UNKNOWN_INSTRUCTION = "unknown-instruction"
    NESTING = "nesting"  # an expression nested deeper than the parser takes
    ADDRESS = "address"  # malformed address or outside the profile
    SYMBOL = "symbol"  # a name that is no declared symbol (softplc.twido.symbols)
    CONSTANT = "constant"  # a literal out of range
    CANNOT_READ = "cannot-read"  # the program file
    # rung structure: an opening instruction missing before, or a closing one after
    NEEDS_LOAD = "needs-load"
    UNMATCHED_CLOSE = "unmatched-close"  # ')' without '('
    NO_MPS = "no-mps"  # MRD / MPP without MPS
    OUTSIDE_BLK = "outside-blk"  # OUT_BLK / END_BLK / a pin without BLK
    AFTER_OUT_BLK = "after-out-blk"  # an input pin after OUT_BLK
    NOT_CLOSED = "not-closed"  # '(' or BLK not closed in the rung
    STRUCTURE = "structure"  # other rung-structure rules (BLK in BLK, stack depth...)
    # names
    LABEL = "label"  # undefined, duplicate, out of range, jump leaving its function
    SUBROUTINE = "subroutine"  # undefined or out of range
    STEP = "step"  # Grafcet step out of range or outside a step
    BLOCK = "block"  # function block unknown, unconfigured, beyond the profile
    IO = "io"  # I/O channel of a module that is not configured
    # values
    TYPE = "type"  # bit/word/float mix, wrong argument type
    READ_ONLY = "read-only"
    FUNCTION = "function"  # unknown function, wrong argument count
    CONTROL = "control"  # RET in main, END in a subroutine
    OTHER = "other"


@dataclass(frozen=True)
class Diagnostic:
    """One problem in a program, with where it is."""

    message: str
    file: str = "<string>"
    line: int = 0
    column: int = 0
    text: str = ""  # the offending text
    expected: str = ""  # what would have been accepted
    code: Code = Code.OTHER

    def __str__(self) -> str:
        # line 0: about the whole file (it cannot be read, ...), no position to give
        where = f"{self.file}:{self.line}:{self.column}" if self.line else self.file
        s = f"{where}: {self.message}"
        if self.text:
            s += f" (at {self.text!r})"
        if self.expected:
            s += f"; expected {self.expected}"
        return s


class ProgramError(SoftPLCError):
    """A program cannot be loaded. Carries every problem found, not only the first."""

    def __init__(self, diagnostics: list[Diagnostic] | Diagnostic | str):
        if isinstance(diagnostics, str):
            diagnostics = [Diagnostic(diagnostics)]
        elif isinstance(diagnostics, Diagnostic):
            diagnostics = [diagnostics]
        self.diagnostics: list[Diagnostic] = list(diagnostics)
        super().__init__("\n".join(str(d) for d in self.diagnostics))

    # Convenience accessors for the first problem.
    @property
    def file(self) -> str:
        return self.diagnostics[0].file

    @property
    def line(self) -> int:
        return self.diagnostics[0].line

    @property
    def column(self) -> int:
        return self.diagnostics[0].column

    @property
    def text(self) -> str:
        return self.diagnostics[0].text

    @property
    def expected(self) -> str:
        return self.diagnostics[0].expected


class ParseError(ProgramError):
    """The program text does not follow the Instruction List syntax."""


class CompileError(ProgramError):
    """The program parses but breaks a rule: unknown object, bad label, type mix..."""


class VerifyError(ProgramError):
    """`softplc verify`: a requirement file or expression is wrong (unknown address, type
    mismatch, a free input the program writes), or the program uses what the verifier
    cannot model (floats, tables...): every problem with its line:col."""


class ConfigCode(StrEnum):
    """What kind of problem a configuration issue is (stable, like `Code` for programs)."""

    UNKNOWN_KEY = "unknown-key"  # a misspelt or misplaced key
    MISSING_KEY = "missing-key"
    TYPE = "type"  # a string for a number, a value for a table...
    VALUE = "value"  # out of range, not one of the choices, not a duration/date/time
    ADDRESS = "address"  # not an address of the profile, or not the kind of object wanted
    CONFLICT = "conflict"  # two settings claim one thing (an output, an input)
    MODULE = "module"  # an expansion module or a channel no module provides
    DEVICE = "device"  # an unknown device type
    FILE = "file"  # the file cannot be read, or is not TOML
    # a file this configuration may not name: from the network, outside --config-dir, a
    # link leading out, not a regular file, too large (softplc.config.files)
    PATH = "path"
    OTHER = "other"


@dataclass(frozen=True)
class ConfigIssue:
    """One problem in a configuration: where (`path`, like `timers."%TM0".preset`), what,
    and its code."""

    path: str
    message: str
    code: ConfigCode = ConfigCode.OTHER

    def __str__(self) -> str:
        return f"{self.path}: {self.message}" if self.path else self.message


def located(issue: ConfigIssue, root: str, code: ConfigCode = ConfigCode.VALUE) -> ConfigIssue:
    """`issue` with a key path: one raised as text (`ConfigError(f"{where}: ...")`, no path
    of its own) gets the key path its text starts with when that is `root` or below it, else
    `root`; an issue of code OTHER gets `code`."""
    if issue.path:
        return issue
    path, sep, message = issue.message.partition(": ")
    code = code if issue.code == ConfigCode.OTHER else issue.code
    if sep and " " not in path and (path == root or path.startswith((root + ".", root + "["))):
        return ConfigIssue(path, message, code)
    return ConfigIssue(root, issue.message, code)


class ConfigError(SoftPLCError):
    """A configuration (dict or TOML) is wrong. Carries every problem found (`issues`), and
    the file they are in when there is one; its text is one `path: message` line each."""

    def __init__(self, issues: str | ConfigIssue | list[ConfigIssue], file: str | None = None):
        if isinstance(issues, str):
            issues = [ConfigIssue("", issues)]
        elif isinstance(issues, ConfigIssue):
            issues = [issues]
        self.issues: list[ConfigIssue] = list(issues)
        self.file = file
        text = "\n".join(str(i) for i in self.issues)
        super().__init__(f"{file}:\n  " + text.replace("\n", "\n  ") if file else text)

    def in_file(self, file: str) -> ConfigError:
        """The same issues, said to be in `file`."""
        return ConfigError(self.issues, file)


class PlantStateError(SoftPLCError):
    """A plant access or fault names no controller, device, wire or link of the plant, or
    asks what its state forbids (restart a running controller)."""


class AddressError(SoftPLCError, ValueError):
    """An address string is malformed or outside the controller profile."""


class BlockError(SoftPLCError, ValueError):
    """A function block's parameters are wrong (timer type, preset range, drum steps...)."""


class MassEstimationError(SoftPLCError):
    """Mass estimation or tuning refused; nothing was written.

    `status` is the code the host reports to the PLC (EST_STATUS, mass-estimation.md §6).
    """

    status = 7


class MassFileError(MassEstimationError):
    """A settings, recording or parameter file is missing or malformed."""

    status = 1


class ChannelMismatchError(MassEstimationError):
    """The channel IDs of the settings and of the recordings differ, or a unit is wrong."""

    status = 2


class CrossingError(MassEstimationError):
    """The acceleration does not cross the margin lines exactly 8 times in the right order."""

    status = 3


class SingularFitError(MassEstimationError):
    """A least-squares fit has no unique solution (too few samples, a flat trace)."""

    status = 4


class UncertaintyError(MassEstimationError):
    """The estimate's relative uncertainty exceeds Acc_uncert. Carries the estimate."""

    status = 5

    def __init__(self, message: str, estimate: object = None):
        super().__init__(message)
        self.estimate = estimate


class TableRowError(MassEstimationError):
    """No row of the parameter table fits the mass (or the mass is not a positive number)."""

    status = 6


class HostError(SoftPLCError):
    """A Modbus host's exchange with the PLC failed (unreachable, timeout, exception)."""
