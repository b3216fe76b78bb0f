"""The seed machines, apart from the core: each in its own package with its host client, its
commands, its devices and what its web view draws. The core never imports them: importing
this package registers the machines' device types (`softplc.devices.base.device_types()`
does so when a configuration names a type the core does not have)."""

from softplc.machines.drawing import pen, trace  # noqa: F401  (each registers its device type)
from softplc.machines.machining import (  # noqa: F401  (likewise)
    centre,
    drive_tuning,
    feed_axis,
    scope,
)

MACHINES = ("drawing", "servo", "cutting", "machining")
