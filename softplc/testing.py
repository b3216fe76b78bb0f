"""pytest plugin: test your own ladder logic in a few lines.

Installed with softplc (entry point `pytest11`), so in any project:

    import pytest

    @pytest.mark.plc_program("ladder_programs/motor.il", config="ladder_programs/motor.toml")
    def test_start_stop(plc):
        plc["%I0.0"] = 1
        plc.scan()
        assert plc["%Q0.0"]

    def test_inline(plc_from_source):
        plc = plc_from_source("LD %I0.0\\nST %Q0.0\\n")
        ...

With hypothesis's `@given`, ask for `plc_factory` (module-scoped, so hypothesis's
function-scoped-fixture health check does not apply) and build a fresh PLC per example:

    @given(st.lists(st.booleans()))
    def test_never_both(plc_factory, presses):
        with plc_factory("motor.il", "motor.toml") as plc:   # cold-started, this example's
            ...

Helpers: `pulse(plc, "%I0.1")` (one-scan pulse), `scan_until(plc, cond, timeout)`.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import pytest

if TYPE_CHECKING:
    from softplc.plc import PLC

P = ParamSpec("P")
T = TypeVar("T")


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "plc_program(path, config=None): the program the `plc` fixture loads")


@pytest.fixture
def plc_from_source() -> Callable[..., PLC]:
    """Factory: plc_from_source(text, config=None) -> PLC on the virtual clock."""
    yield from closing_factory(_plc_class().from_source)


@pytest.fixture
def plc(request: pytest.FixtureRequest) -> PLC:
    """The PLC named by the test's `plc_program` marker, cold-started, virtual clock."""
    marker = request.node.get_closest_marker("plc_program")
    if marker is None:
        pytest.fail("the `plc` fixture needs @pytest.mark.plc_program(path, config=...)")
    path = locate(request, marker.args[0])
    config = marker.kwargs.get("config", marker.args[1] if len(marker.args) > 1 else None)
    if isinstance(config, (str, Path)):
        config = locate(request, config)
    p = _plc_class().from_file(path, config)
    yield p
    p.close()


@pytest.fixture(scope="module")
def plc_factory(request: pytest.FixtureRequest) -> Callable[..., PLC]:
    """Factory for tests that need a fresh PLC per call, as hypothesis's `@given` examples
    do: `plc_factory(path=None, config=None, **kw)` -> a cold-started PLC on the virtual
    clock, to use as `with plc_factory(...) as plc:`. Paths are found as the marker's
    (the test file's folder, the rootdir, the current directory); without a path, the
    module's `pytestmark = pytest.mark.plc_program(...)`. Module-scoped: a function-scoped
    fixture runs once for all of a `@given` test's examples, which hypothesis refuses
    (HealthCheck.function_scoped_fixture); the factory holds no PLC state between calls.
    PLCs not closed by their `with` are closed when the module's tests end."""
    made: weakref.WeakSet[PLC] = weakref.WeakSet()  # closed and dropped ones go

    def make(path: str | Path | None = None, config: Any = None, **kw: Any) -> PLC:
        if path is None:
            marker = request.node.get_closest_marker("plc_program")
            if marker is None:
                pytest.fail("plc_factory() needs a program: plc_factory('x.il', 'x.toml') "
                            "or the module's pytestmark = pytest.mark.plc_program(...)")
            path = marker.args[0]
            config = marker.kwargs.get("config",
                                       marker.args[1] if len(marker.args) > 1 else None)
        if isinstance(config, (str, Path)):
            config = locate(request, config)
        p = _plc_class().from_file(locate(request, path), config, **kw)
        made.add(p)
        return p

    yield make
    for p in list(made):
        p.close()


def _plc_class() -> type[PLC]:
    """softplc.plc on first use: pytest loads this plugin in every run, whatever the
    project, and the PLC brings the compiler and pydantic (half a second) with it."""
    from softplc.plc import PLC

    return PLC


def closing_factory(build: Callable[P, T]) -> Iterator[Callable[P, T]]:
    """A factory fixture's body (`yield from`): `build`, and what it made closed when the
    test ends."""
    made: list[T] = []

    def make(*args: P.args, **kw: P.kwargs) -> T:
        made.append(build(*args, **kw))
        return made[-1]

    yield make
    for x in made:
        x.close()  # type: ignore[attr-defined]


def locate(request: pytest.FixtureRequest, name: str | Path) -> Path:
    """A marker's file: relative to the test file's folder, as a user writes it next to
    the test (`pytest /elsewhere/test_motor.py` then works from any directory); else to
    the rootdir or the current directory, where earlier projects put their paths."""
    here = Path(str(request.node.path)).parent
    root = Path(str(request.config.rootpath))
    path = Path(name)
    if path.is_absolute():
        return path
    for base in (here, root, Path.cwd()):
        if (base / path).exists():
            return base / path
    return here / path  # missing: the error names the test file's folder


def pulse(plc: PLC, address: str, scans: int = 1) -> None:
    """Hold a bit at 1 for `scans` scans, then release it to 0 and scan once more."""
    plc[address] = 1
    plc.scan(scans)
    plc[address] = 0
    plc.scan()


def scan_until(plc: PLC, condition: Callable[[PLC], Any], timeout: float = 10.0) -> PLC:
    """Scan until condition(plc) holds; fail the test after `timeout` s of PLC time."""
    if not plc.run_until(condition, timeout):
        pytest.fail(f"condition not met within {timeout} s of PLC time "
                    f"(t = {plc.time:.3f} s, {plc.scan_count} scans)")
    return plc
