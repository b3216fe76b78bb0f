"""Generic simulated devices: they read the PLC's field outputs and write its field inputs.
A machine's own devices live in its package under `softplc.machines`."""

from softplc.devices import (  # noqa: F401  (each registers its device type)
    analog_source,
    axis,
    encoder,
    oven,
    stepper,
    switches,
)
from softplc.devices.base import DEVICE_TYPES, Device, build_devices, device_types, register_device

__all__ = ["Device", "DEVICE_TYPES", "build_devices", "device_types", "register_device"]
