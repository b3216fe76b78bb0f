"""Generic simulated devices: they read the PLC's field outputs and write its field inputs.
A machine's own devices live in its package under `softplc.machines`. Each device's module
is imported when a configuration names its type (`device_types()`, the catalog in
`softplc.devices.base`), not with this package."""

from softplc.devices.base import DEVICE_TYPES, Device, build_devices, device_types, register_device

__all__ = ["Device", "DEVICE_TYPES", "build_devices", "device_types", "register_device"]
