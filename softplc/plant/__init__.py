"""A plant of soft Twidos (issue 35): several controllers, their Remote Links, wires and
shared devices, from a plant file (`model.py`), run in one process on one virtual clock
(`plant.py`)."""

from softplc.errors import PlantStateError
from softplc.plant.model import PlantError, PlantSpec, load_plant
from softplc.plant.plant import Plant

__all__ = ["Plant", "PlantError", "PlantSpec", "PlantStateError", "load_plant"]
