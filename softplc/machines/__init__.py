"""The seed machines, apart from the core: each in its own package with its host client, its
commands, its devices and what its web view draws (drawing, servo, cutting, machining; gcode
is the G-code reader the drawing and cutting tables share). The core never imports them:
`softplc.machines.devices` names their device types' modules, read by
`softplc.devices.base.device_types()`, which imports a type's module when a configuration
names it."""

MACHINES = ("drawing", "servo", "cutting", "machining")
