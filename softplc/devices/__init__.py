"""Simulated machines: devices that read the PLC's field outputs and write its field inputs."""

from . import (  # noqa: F401  (each registers its device type)
    analog_source,
    axis,
    drive_tuning,
    encoder,
    feed_axis,
    oven,
    pen,
    scope,
    stepper,
    switches,
    trace,
)
from .base import DEVICE_TYPES, Device, build_devices, register_device

__all__ = ["Device", "DEVICE_TYPES", "build_devices", "register_device"]
