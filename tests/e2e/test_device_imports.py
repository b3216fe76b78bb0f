"""A PLC imports the modules of the device types its configuration names, and no other
(the catalog of softplc/devices/base.py): a program without devices starts without any
device module, the machines' packages or numpy. In a fresh interpreter, as `softplc run`
starts: the test process has imported them all long before."""

from __future__ import annotations

import json
import subprocess
import sys

CODE = """
import json, sys
from softplc import PLC

def new_since(before):
    return sorted(m for m in set(sys.modules) - before
                  if m.startswith(("softplc.devices", "softplc.machines")) or m == "numpy")

program = "LD %I0.0\\nST %Q0.0\\n"
before = set(sys.modules)
PLC.from_source(program, config={"scan_period": "10ms"})
bare = new_since(before)
before = set(sys.modules)
plc = PLC.from_source(program, config={"devices": {"start": {"type": "push_button",
                                                             "input": "%I0.0"}}})
plc.devices["start"].press()
plc.scan(2)  # the button writes its input after a scan; the next one reads it
print(json.dumps({"bare": bare, "button": new_since(before), "q": plc["%Q0.0"]}))
"""


def test_a_plc_imports_only_the_device_modules_its_configuration_names():
    out = json.loads(subprocess.run([sys.executable, "-c", CODE], capture_output=True,
                                    text=True, check=True).stdout)
    # no device: the catalog's names only (the core's registry, the machines' list)
    assert out["bare"] == ["softplc.devices", "softplc.devices.base", "softplc.machines",
                           "softplc.machines.devices"]
    # one push button: its module alone, and the device works (the program sees it)
    assert out["button"] == ["softplc.devices.switches"]
    assert out["q"] is True
