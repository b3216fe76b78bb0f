"""pytest plugin for plants (issue 35): a line's behaviour tested like one program's.

Installed with softplc (entry point `pytest11`, `softplc_plant`):

    @pytest.mark.plant_file("ladder_programs/plant/plant.toml")
    def test_line_runs(plant):
        plant["master:%I0.0"] = 1
        plant.run(30.0)
        assert plant["master:%MW0"] > 0

    def test_other(plant_from_file):
        plant = plant_from_file("my_plant.toml")

The file is found as `softplc.testing` finds a program: next to the test file, else from
the rootdir or the current directory.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from softplc.testing import closing_factory, locate

if TYPE_CHECKING:
    from softplc.plant import Plant


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "plant_file(path): the plant the `plant` fixture loads")


@pytest.fixture
def plant_from_file(request: pytest.FixtureRequest) -> Iterator[Callable[[str | Path], Plant]]:
    """Factory: plant_from_file(path) -> a Plant at time 0 (closed after the test)."""
    from softplc.plant import Plant  # on first use: pytest loads this plugin in every run

    yield from closing_factory(lambda path: Plant.from_file(locate(request, path)))


@pytest.fixture
def plant(request: pytest.FixtureRequest,
          plant_from_file: Callable[[str | Path], Plant]) -> Plant:
    """The plant named by the test's `plant_file` marker, at time 0."""
    marker = request.node.get_closest_marker("plant_file")
    if marker is None:
        pytest.fail("the `plant` fixture needs @pytest.mark.plant_file(path)")
    return plant_from_file(marker.args[0])
