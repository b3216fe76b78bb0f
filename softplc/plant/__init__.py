"""A plant of soft Twidos (issue 35): several controllers, their Remote Links, wires and
shared devices, from a plant file (`model.py`), run in one process on one virtual clock
(`plant.py`)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from softplc.errors import PlantStateError

if TYPE_CHECKING:
    from softplc.plant.model import PlantError, PlantSpec, load_plant
    from softplc.plant.plant import Plant

__all__ = ["Plant", "PlantError", "PlantSpec", "PlantStateError", "load_plant"]
# name -> its module, imported on first use (PEP 562): the pytest plugin
# (softplc.plant.testing) is a submodule, loaded by every pytest run, and the plant's
# modules bring the PLC, the configuration and pydantic with them (half a second)
_LAZY = {"Plant": "softplc.plant.plant", "PlantError": "softplc.plant.model",
         "PlantSpec": "softplc.plant.model", "load_plant": "softplc.plant.model"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
