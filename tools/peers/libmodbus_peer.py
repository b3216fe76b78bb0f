"""The libmodbus C server (Debian libmodbus-dev), compiled with gcc in a temporary folder."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from .modbus_peer import ServerProcess

SOURCE = Path(__file__).with_name("libmodbus_server.c")


def build(folder: Path) -> Path:
    """Compile the server into `folder`; raises RuntimeError saying what is missing."""
    if not shutil.which("gcc"):
        raise RuntimeError("gcc not installed")
    if not Path("/usr/include/modbus/modbus.h").exists():
        raise RuntimeError("libmodbus-dev not installed (apt-get install libmodbus-dev)")
    exe = folder / "libmodbus_server"
    r = subprocess.run(["gcc", "-O2", str(SOURCE), "-o", str(exe), "-I/usr/include/modbus",
                        "-lmodbus"], capture_output=True, text=True)
    if r.returncode:
        raise RuntimeError(f"gcc failed: {r.stderr.strip().splitlines()[-1:]}")
    return exe


class LibmodbusServer(ServerProcess):
    def __init__(self) -> None:
        self._tmp = tempfile.TemporaryDirectory(prefix="softplc-bench-")
        try:
            exe = build(Path(self._tmp.name))
            super().__init__([str(exe), "0"], r"^listening (\d+)")
        except Exception:
            self._tmp.cleanup()
            raise

    def stop(self) -> None:
        super().stop()
        self._tmp.cleanup()


def version() -> str | None:
    r = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libmodbus-dev"],
                       capture_output=True, text=True)
    return r.stdout.strip() or None if r.returncode == 0 else None
