"""The device interface: the whole contract between the scan engine and a simulated machine.

After every scan the engine calls `update(t, dt)` on each device, in configuration order
(and `cold_start()` when a cold start has just cleared the memory).
A device reads the field outputs (`mem.q_field`, published at the end of the scan), moves
its physics on by `dt` seconds to time `t`, and writes field inputs (`mem.i_field`), which
the next scan latches into its input image. Devices resolve their addresses once, in
`bind`, into (buffer, index) pairs, so `update` costs a few list lookups per scan.

Options: each device class declares its TOML options as a pydantic model, the class
attribute `Options` (a `softplc.config.Section`: unknown keys refused, no silent type
conversion; field types such as `Duration`, `FiniteFloat`, `Address` from `softplc.config`).
The configuration is checked against it with the rest of the schema, and the device is
built from the validated model: `Stepper(name, Stepper.Options(phases=[...]))`. What needs
the memory image or other devices (does the address exist, is `axis` a stepper) is checked
in `bind`, as a ConfigError naming `devices.NAME.option`.
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Callable, Iterator, Mapping
from typing import Any, Protocol

from softplc.config import Section, validate_config
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue, located
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address


class WordCheck(Protocol):
    """A device's check of the values a host writes into its words: the access port and
    the Modbus server ask it before queueing a write, so a value the device would refuse
    is refused where it was made. Called from a front-end's thread: settings only."""

    def ranges(self) -> list[tuple[int, int]]:
        """%MW ranges [start, stop) whose writes `refusal` checks."""
        ...

    def refusal(self, kind: str, index: int, value: float) -> str | None:
        """Why `value` written to %MW/%MD/%MF`index` (`kind` "MW", "MD" or "MF") is
        refused, None if it is taken (or the word is not checked)."""
        ...


class Device:
    """Base class of simulated devices. `name` is the key in the machine config."""

    #: the check of a host's writes into this device's words (None: none)
    word_check: WordCheck | None = None

    type_name = "device"
    # The simulated state, declared by each device: attributes holding immutable values
    # (numbers, strings, tuples, paths), and records: lists only ever appended to, or
    # replaced by a new list (a reset, a new recording), kept as (the list, its length).
    STATE: tuple[str, ...] = ()
    RECORDS: tuple[str, ...] = ()

    class Options(Section):
        """No options."""

    def __init__(self, name: str, options: Any = None):
        self.name = name
        self.options = options if options is not None else self.Options()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        """Resolve addresses (and other devices this one depends on) once."""

    def update(self, t: float, dt: float) -> None:
        """Read field outputs, advance the physics by dt, write field inputs."""

    def reset(self) -> None:
        """Back to the configured initial state."""

    def cold_start(self) -> None:
        """The engine has just cleared %M and %MW (a cold start, the first one at build):
        a device that keeps words of its own there writes them again now, before a host's
        write can land in the cleared words (the next scan's first step)."""

    def state(self) -> dict[str, Any]:
        """The simulated state (for the debugger's `back`, its history, retained state)."""
        st: dict[str, Any] = {k: getattr(self, k) for k in self.STATE}
        for k in self.RECORDS:
            rec = getattr(self, k)
            st[k] = (rec, len(rec))
        return st

    def set_state(self, st: dict[str, Any]) -> None:
        """Back to a `state()`: records are the list they were, cut back to its length."""
        for k in self.STATE:
            setattr(self, k, st[k])
        for k in self.RECORDS:
            rec, n = st[k]
            del rec[n:]
            setattr(self, k, rec)

    def status(self) -> dict[str, Any]:
        """A short state summary for the daemon's statistics line and the debugger."""
        return {}

    def view(self, since_t: float) -> dict[str, Any] | None:
        """What the web monitor's Machine tab needs to draw this device (None: no drawing),
        with `since_t` the machine time of the page's last sample. Called in the scan thread,
        between two scans: plain attribute and memory reads only."""
        return None

    def panels(self) -> dict[str, Any]:
        """Panels of the Machine tab that this device describes beside its drawing, by name
        (the mass estimator's words for a machine's scope). Same thread rule as `view`."""
        return {}

    def close(self) -> None:
        """End of the run: flush files (e.g. the trace CSV). Called once by the owner."""

    def read_only_words(self) -> list[tuple[int, int]]:
        """%MW ranges [start, stop) this device writes (status words): the daemon makes
        them read-only for Modbus hosts (a write there gets exception 02)."""
        return []

    # -- helpers for bind() ------------------------------------------------------------------
    def io_index(self, mem: MemoryImage, address: Any, kind: str, option: str) -> int:
        """Flat index of an `%I` or `%Q` (kind) bit, with a config error naming the option."""
        if not isinstance(address, str):
            raise self.problem(option, f"expected an address string (got {address!r})",
                               ConfigCode.TYPE)
        try:
            ref = parse_address(address, mem.profile)
        except AddressError as e:
            raise self.problem(option, str(e), ConfigCode.ADDRESS) from None
        if ref.kind != kind or ref.bit is not None or ref.length is not None \
                or ref.field is not None:
            raise self.problem(option, f"expected a %{kind} bit address (got {address!r})",
                               ConfigCode.ADDRESS)
        mem.use_io(ref)
        return ref.index

    def peer(self, devices: dict[str, Device], name: Any, cls: type, option: str) -> Any:
        """The device called `name`, checked to be a `cls` (e.g. a switch's axis)."""
        dev = devices.get(name) if isinstance(name, str) else None
        if not isinstance(dev, cls):
            kind = getattr(cls, "type_name", cls.__name__)
            raise self.problem(option, f"{name!r} is not a {kind} device of this machine",
                               ConfigCode.DEVICE)
        return dev

    def where(self, option: str) -> str:
        """The key path of one of this device's options, for error messages."""
        return f"devices.{self.name}.{option}"

    def problem(self, option: str, message: str,
                code: ConfigCode = ConfigCode.VALUE) -> ConfigError:
        """The error to raise for one of this device's options: one issue at its key path
        (`build_devices` collects every device's)."""
        return ConfigError(ConfigIssue(self.where(option), message, code))


class AxisDevice(Device):
    """A device with a position along a travel: what limit switches watch. Positions are
    in the axis's own units (a stepper's motor steps, a servo axis's encoder counts), home
    at 0, the far end at `axis_end()`."""

    type_name = "stepper or servo_axis"  # for error messages; subclasses register their own

    def axis_position(self) -> float:
        raise NotImplementedError

    def axis_end(self) -> float:
        """The position from which an `at = "end"` switch is made."""
        raise NotImplementedError

    def trace_position(self) -> float:
        """The position a trace records (default: the true position, axis units)."""
        return self.axis_position()

    def missed(self) -> int:
        """Steps lost so far (a stepper's missed steps; 0 for a closed-loop axis)."""
        return 0


#: The device types registered so far (`register_device`), by type name: those whose
#: modules have been imported. `device_types()` is the whole catalog.
DEVICE_TYPES: dict[str, type[Device]] = {}

#: The core's device types, by the module that defines each one (`register_device` there):
#: a module is imported the first time a configuration names one of its types, so a PLC
#: without devices imports none (and a stepper's machine does not import the servo axis's
#: numpy). tests/unit/test_device_catalog.py checks it against the modules' decorators.
DEVICE_MODULES: dict[str, str] = {
    "analog_source": "softplc.devices.analog_source",
    "encoder": "softplc.devices.encoder",
    "limit_switch": "softplc.devices.switches",
    "oven": "softplc.devices.oven",
    "push_button": "softplc.devices.switches",
    "servo_axis": "softplc.devices.axis.servo",
    "stepper": "softplc.devices.stepper",
}

#: The module that names the machines' own device types, its `DEVICE_MODULES` the same way
#: (a plug-in: the core names it, never imports from it).
MACHINE_PLUGINS = "softplc.machines.devices"


class DeviceTypes(Mapping[str, type[Device]]):
    """Device type name -> class, every type of the catalog (the core's and the machines')
    listed, a type's module imported on first lookup."""

    def __init__(self, modules: Mapping[str, str]):
        self.modules = dict(modules)

    def __getitem__(self, type_name: str) -> type[Device]:
        module = self.modules[type_name]  # KeyError: not a device type
        if type_name not in DEVICE_TYPES:
            importlib.import_module(module)
            if type_name not in DEVICE_TYPES:  # the catalog is wrong: a defect, not input
                raise ImportError(f"{module} registers no device type {type_name!r}")
        return DEVICE_TYPES[type_name]

    def __contains__(self, type_name: object) -> bool:  # Mapping's would import the module
        return type_name in self.modules

    def __iter__(self) -> Iterator[str]:
        return iter(self.modules)

    def __len__(self) -> int:
        return len(self.modules)


@functools.cache
def device_types() -> DeviceTypes:
    """Every device type, the machines' included, each one's module imported when it is
    looked up (`types["stepper"]`, `.get`, `.items()`); the names alone (`in`, iteration,
    an unknown type's error message) import none. The core depends on no machine: their
    catalog comes from MACHINE_PLUGINS, a module of names only."""
    machines = importlib.import_module(MACHINE_PLUGINS).DEVICE_MODULES
    both = DEVICE_MODULES.keys() & machines.keys()
    if both:
        raise ImportError(f"device types both in the core and a machine: {sorted(both)}")
    return DeviceTypes({**DEVICE_MODULES, **machines})


def finite_or_none(v: float | None) -> float | None:
    """`v` for a view sent as JSON, None where it is missing, infinite or NaN."""
    return v if v is not None and math.isfinite(v) else None


def interp(table: list[tuple[float, float]], x: float) -> float:
    """Piecewise-linear value of a table of (x, y) points at x, constant beyond its ends
    (an analog profile over time, a load over position). A loop rather than numpy.interp:
    called on scalars every scan, where numpy's call costs more than the search."""
    if x <= table[0][0]:
        return table[0][1]
    for (x0, y0), (x1, y1) in zip(table, table[1:], strict=False):
        if x <= x1:
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    return table[-1][1]


def register_device(type_name: str) -> Callable[[type[Device]], type[Device]]:
    def deco(cls: type[Device]) -> type[Device]:
        cls.type_name = type_name
        DEVICE_TYPES[type_name] = cls
        return cls

    return deco


def build_devices(config: dict[str, Any], mem: MemoryImage) -> dict[str, Device]:
    """Create and bind a machine's devices, in order. `config` maps a device name to its
    `[devices.NAME]` table (a dict with `type`), or to (type, validated Options). Raises
    one ConfigError with every device's problems, each at its key path: those of creating
    them, else those of binding them (binding needs every device made: a switch's axis)."""
    devices: dict[str, Device] = {}
    issues: list[ConfigIssue] = []

    def collect(name: str, step: Callable[[], Any]) -> None:
        try:
            step()
        except ConfigError as e:
            issues.extend(located(i, f"devices.{name}") for i in e.issues)

    def create(name: str, entry: Any) -> None:
        if isinstance(entry, tuple):
            type_name, options = entry
        else:  # a raw table: checked against the same schema as a whole configuration
            section = validate_config({"devices": {name: entry}}, device_types()).devices[name]
            type_name, options = section.type, section.options
        devices[name] = device_types()[type_name](name, options)

    for name, entry in config.items():
        collect(name, lambda: create(name, entry))  # noqa: B023 (called at once)
    if not issues:
        for name, dev in devices.items():
            collect(name, lambda: dev.bind(mem, devices))  # noqa: B023
    if issues:
        raise ConfigError(issues)
    return devices
