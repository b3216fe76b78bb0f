"""Importing this module registers the machines' own device types (the core's
`softplc.devices.base.device_types()` imports it as a plug-in the first time a configuration
is read: the core never imports a machine)."""

from softplc.machines.drawing import pen, trace  # noqa: F401  (each registers its device type)
from softplc.machines.machining import (  # noqa: F401  (likewise)
    centre,
    drive_tuning,
    feed_axis,
    scope,
)
