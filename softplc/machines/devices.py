"""The machines' own device types, by the module that defines each one (its
`register_device`): `softplc.devices.base.device_types()` reads this catalog as a plug-in
(the core never imports a machine) and imports a type's module only when a configuration
names it. Names only here: importing this module imports no machine.
tests/unit/test_device_catalog.py checks it against the modules' decorators."""

DEVICE_MODULES: dict[str, str] = {
    "drive_tuning": "softplc.machines.machining.drive_tuning",
    "feed_axis": "softplc.machines.machining.feed_axis",
    "pen": "softplc.machines.drawing.pen",
    "scope": "softplc.machines.machining.scope",
    "torch": "softplc.machines.drawing.pen",
    "trace": "softplc.machines.drawing.trace",
}
