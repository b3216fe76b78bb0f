"""Every registered device type declares its simulated state (`STATE`, `RECORDS`): a
`state()`/`set_state()` round trip gives back whatever `update()` changed, so
`Engine.snapshot()/restore()`, the debugger's `back` and its history cover every device."""

from __future__ import annotations

import random
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from softplc import PLC
from softplc.devices import Device, device_types

ROOT = Path(__file__).resolve().parents[2] / "ladder_programs"
MACHINES = ("drawing_table", "cutting_table", "mass_tuning", "analog_thermostat", "fast_counter",
            "mass_tuning_ideal")
IDEAL = "_ideal"  # a shipped machine with its servo axes made ideal feed axes
SCOPE_START, SCOPE_STOP = 1, 2  # devices/scope.py SW.START, SW.STOP


def machine(name: str, tmp: Path) -> PLC:
    """A shipped machine, writing no files outside `tmp`; the thermostat also gets an
    analog source (no shipped machine has one) on the base potentiometer."""
    ideal = name.endswith(IDEAL)
    name = name.removesuffix(IDEAL)
    cfg: dict[str, Any] = tomllib.loads((ROOT / f"{name}.toml").read_text(encoding="utf-8"))
    for dev in cfg["devices"].values():
        if ideal and dev["type"] == "servo_axis":
            dev["type"] = "feed_axis"
        if dev["type"] == "scope":
            dev["directory"] = str(tmp)
        if dev["type"] == "trace":
            dev.pop("csv", None)
    if name == "analog_thermostat":
        cfg["devices"]["knob"] = {"type": "analog_source", "input": "%IW0.0",
                                  "profile": [[0, 0.0], [1, 1.0]]}
    return PLC.from_file(ROOT / f"{name}.il", config=cfg)


def lacks_state(dev: Device) -> bool:
    return not (type(dev).STATE or type(dev).RECORDS)


def copy(v: Any) -> Any:
    return v.copy() if isinstance(v, list | dict | np.ndarray) else v


def same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and \
            np.array_equal(a, b)
    return bool(a == b)


def stir(plc: PLC, rng: random.Random, scans: int) -> None:
    """Scans with random field outputs (steppers step, pens and heaters switch) and the
    scope recording, as the devices see them after a scan."""
    scopes = [d for d in plc.devices.values() if d.type_name == "scope"]
    for _ in range(scans):
        plc.scan()
        for i in range(len(plc.mem.q_field)):
            plc.mem.q_field[i] = rng.randint(0, 1)
        for sc in scopes:
            sc._w[sc._base] = SCOPE_START if rng.random() < 0.2 else 0
        for dev in plc.devices.values():
            dev.update(plc.time, plc.scan_period)


def image_parts(plc: PLC) -> set[int]:
    """The memory image's buffers (ids): devices hold them, they are not device state."""
    parts = {id(plc.mem)}
    for v in vars(plc.mem).values():
        parts.add(id(v))
        parts.update(id(w) for w in getattr(v, "__dict__", {}).values())
    return parts


def observed(plc: PLC, dev: Device) -> dict[str, Any]:
    """The device's attributes, except the memory image and other devices it holds."""
    image = image_parts(plc)
    return {k: copy(v) for k, v in vars(dev).items()
            if not isinstance(v, Device) and id(v) not in image
            and k not in ("options", "opt")}


def test_the_machines_cover_every_device_type(tmp_path):
    seen = {d.type_name for m in MACHINES for d in machine(m, tmp_path).devices.values()}
    assert seen == set(device_types())


@pytest.mark.parametrize("name", MACHINES)
def test_device_state_round_trip_gives_back_what_update_changed(name, tmp_path):
    plc = machine(name, tmp_path)
    rng = random.Random(1)
    stir(plc, rng, 50)
    before = {n: observed(plc, d) for n, d in plc.devices.items()}
    states = {n: d.state() for n, d in plc.devices.items()}
    stir(plc, rng, 80)
    missing = []
    for n, dev in plc.devices.items():
        if lacks_state(dev):
            continue
        dev.set_state(states[n])
        for k, v in observed(plc, dev).items():
            if k in before[n] and not same(v, before[n][k]):
                missing.append(f"{type(dev).__name__}.{k}")
    assert not missing, f"not in STATE/RECORDS: {sorted(set(missing))}"
    if any(lacks_state(d) for d in plc.devices.values()):
        pytest.xfail("servo_axis declares no STATE yet (devices/axis/ is being rewritten)")


@pytest.mark.parametrize("name", MACHINES)
def test_engine_snapshot_restore_round_trip_changes_nothing(name, tmp_path):
    plc = machine(name, tmp_path)
    rng = random.Random(2)
    stir(plc, rng, 40)
    snap = plc.engine.snapshot()
    plc.engine.restore(snap)  # at once: nothing changes
    assert plc.engine.snapshot() == snap
    seen = {n: observed(plc, d) for n, d in plc.devices.items()}
    stir(plc, rng, 40)
    plc.engine.restore(snap)
    assert plc.engine.snapshot() == snap
    if any(lacks_state(d) for d in plc.devices.values()):
        pytest.xfail("servo_axis declares no STATE yet (devices/axis/ is being rewritten)")
    for n, dev in plc.devices.items():
        assert all(same(v, seen[n][k]) for k, v in observed(plc, dev).items() if k in seen[n]), n
