"""Issue 31 item 1: a configuration received with an online change names no file of the
host. Each attack of round 3 (`symbols_file = "/etc/passwd"`, `"/dev/zero"`, a FIFO, a
symbolic link out, `..`) is refused with code `path`, quotes nothing of the file, and the
next online change still works (softplc.config.files, softplc.access.program)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from softplc import online
from softplc.access.program import ProgramAccess
from softplc.config.files import MAX_FILE_BYTES, Local, read_bounded
from softplc.errors import ConfigCode, ConfigError
from softplc.plc import PLC

ROOT = Path(__file__).resolve().parents[2]
STAR = ROOT / "ladder_programs" / "star_delta.il"
SOURCE = STAR.read_text()
CONFIG = (STAR.with_suffix(".toml")).read_text()
SECRET = "root:x:0:0:SECRET-LINE\n"  # what must never come back in a message


def with_symbols(name: str) -> dict:
    import tomllib

    return tomllib.loads(CONFIG) | {"symbols_file": name}


@pytest.fixture
def access(tmp_path):
    """The star-delta PLC and its access port; --config-dir = tmp_path/cfg, beside a
    secret file outside it."""
    plc = PLC.from_file(STAR, STAR.with_suffix(".toml"))
    (tmp_path / "cfg").mkdir()
    (tmp_path / "secret.csv").write_text(SECRET)
    yield ProgramAccess(plc, files_root=tmp_path / "cfg"), tmp_path
    plc.close()


def refused(access: ProgramAccess, name: str, *, files=None) -> str:
    with pytest.raises(ConfigError) as e:
        access.plan(SOURCE, with_symbols(name), "x.il", files)
    assert [i.code for i in e.value.issues] == [ConfigCode.PATH], e.value.issues
    assert e.value.issues[0].path == "symbols_file"
    text = str(e.value)
    assert "SECRET" not in text and "root:" not in text
    return text


def still_changes(access: ProgramAccess) -> None:
    """A good change goes through after the refusals (nothing wedged)."""
    change, _ = access.plan(SOURCE.replace("%MW11", "%MW13"), None, "ok.il")
    online.apply(access.plc, change, confirm=True)
    assert access.plc.program_version == 1
    assert access.plc.symbols.get("STARTS") is not None  # the running file, from memory


def test_host_files_are_refused_without_a_config_dir(access):
    port, tmp = access
    port.files_root = None
    for name in ("/etc/passwd", "/dev/zero", str(tmp / "secret.csv"), "star_delta_symbols.csv.x"):
        assert "names no file of the host" in refused(port, name)
    still_changes(port)


def test_paths_leading_out_of_the_config_dir_are_refused(access):
    port, tmp = access
    cfg = tmp / "cfg"
    (cfg / "out.csv").symlink_to(tmp / "secret.csv")
    (cfg / "zero.csv").symlink_to("/dev/zero")
    assert "without '..'" in refused(port, "../secret.csv")
    assert "without '..'" in refused(port, "/etc/passwd")
    assert "leads out" in refused(port, "out.csv")
    assert "leads out" in refused(port, "zero.csv")
    still_changes(port)


def test_a_fifo_a_folder_and_a_huge_file_are_refused_without_waiting(access):
    port, tmp = access
    cfg = tmp / "cfg"
    os.mkfifo(cfg / "pipe.csv")  # nobody writes: opening it to read would block for ever
    (cfg / "folder.csv").mkdir()
    with open(cfg / "big.csv", "wb") as f:
        f.truncate(MAX_FILE_BYTES + 1)  # sparse: the size is refused before any read
    assert "not a regular file" in refused(port, "pipe.csv")
    assert "not a regular file" in refused(port, "folder.csv")
    assert f"over the {MAX_FILE_BYTES}" in refused(port, "big.csv")
    still_changes(port)


def test_files_come_with_the_request_or_from_under_the_config_dir(access):
    port, tmp = access
    csv = "%MW20,SPEED,belt speed\n"
    change, names = port.plan(SOURCE, with_symbols("mine.csv"), "x.il", {"mine.csv": csv.encode()})
    assert names.get("SPEED").address == "%MW20" and change.files == {"mine.csv": csv.encode()}
    (tmp / "cfg" / "disk.csv").write_text("%MW21,LENGTH,\n")
    _, names = port.plan(SOURCE, with_symbols("disk.csv"), "x.il")
    assert names.get("LENGTH").address == "%MW21"


def test_a_binary_symbol_file_is_a_coded_error(access):
    port, _ = access
    with pytest.raises(ConfigError, match="not a text file") as e:
        port.plan(SOURCE, with_symbols("b.csv"), "x.il", {"b.csv": b"\x00\x81\x8d" * 10})
    assert "\\x" not in str(e.value)


def test_the_local_reader_refuses_devices_and_fifos_too(tmp_path):
    """A configuration from the command line names any path, read as safely."""
    os.mkfifo(tmp_path / "p")
    for path, why in ((Path("/dev/zero"), "not a regular file"),
                      (tmp_path / "p", "not a regular file"), (tmp_path, "not a regular file")):
        with pytest.raises(ConfigError, match=why):
            read_bounded(path, "symbols_file", "symbol file")
    (tmp_path / "s.csv").write_text(SECRET)
    assert Local().read("s.csv", tmp_path, "symbols_file", "symbol file") == SECRET.encode()


def test_a_network_configuration_writes_no_file(access):
    """A device's output file from a configuration received over the network is refused
    (online change builds no device; the policy refuses the path anyway)."""
    from softplc.config.files import Carried

    with pytest.raises(ConfigError, match="writes no file") as e:
        Carried().output("/etc/cron.d/x", None, "devices.trace.csv")
    assert e.value.issues[0].code == ConfigCode.PATH
