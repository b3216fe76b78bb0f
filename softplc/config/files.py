"""Where the files a configuration names may come from, and how they are read.

A configuration names files: `symbols_file` (read), a device's `csv` or `trace_csv`
(written). Given on the command line, a configuration is the operator's and so are its
files: `Local` reads any path, relative to the configuration's folder. A configuration that
comes over the network (an online change: POST /api/program, `softplc load`, the access
port) is not: a page or a host must never reach the file system with it (issue 31: one
named `/etc/passwd` and had its second line echoed, `/dev/zero` grew the daemon to 1.5 GB, a
FIFO wedged online change for good). `Carried` serves the files the request carries, by
the name the configuration gives them, then, only if the operator named a folder on the
daemon's command line (`softplc run --config-dir DIR`), regular files under that folder;
anything else is refused, and it writes no file at all.

Every file read from disk, by either policy, is opened without blocking (a FIFO or a
device does not wedge the reader), must be a regular file, is size-capped before it is read
and read against a deadline (`softplc.limits.read_regular`); an error says what is wrong with
the file, never what is in it.
The files a policy served are recorded (`served`): an online change keeps them with its
program (`softplc.persist.kept`), so a restart rebuilds it without reading them again.
"""

from __future__ import annotations

import posixpath
from collections.abc import Mapping
from pathlib import Path

from softplc.errors import ConfigCode, ConfigError, ConfigIssue
from softplc.limits import FileRefused, read_regular

#: The largest file a configuration may name: a TwidoSuite symbol table of every object
#: of a TWDLCAE40DRF (3,000 %MW, 256 %M, ... with 200-character comments) is under 1 MiB.
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Seconds a file may take to read (a regular file on a local disk takes milliseconds;
#: this bounds a stalled network mount, not a normal read).
READ_DEADLINE_S = 5.0
#: Files one request may carry (a configuration names one symbol file today).
MAX_CARRIED_FILES = 16
MAX_NAME_LENGTH = 255  # characters of a carried file's name (a POSIX file name's bytes)


def _refused(key: str, message: str) -> ConfigError:
    return ConfigError(ConfigIssue(key, message, ConfigCode.PATH))


def read_bounded(path: Path, key: str, what: str, limit: int = MAX_FILE_BYTES,
                 deadline_s: float = READ_DEADLINE_S, follow: bool = True) -> bytes:
    """The bytes of the regular file `path` (`softplc.limits.read_regular`: not
    blocking, size-capped, with a deadline); ConfigError at `key` (code `path` for a file
    that may not be read, `file` for one that cannot be), naming the file, never quoting
    it."""
    try:
        return read_regular(path, what, limit, deadline_s, follow)
    except FileRefused as e:
        raise ConfigError(ConfigIssue(key, str(e), ConfigCode.PATH if e.refused
                                      else ConfigCode.FILE)) from None


class FilePolicy:
    """Where the files a configuration names come from: `read` one (bytes), `output` a
    path to write to. `served` records each file read, by the name the configuration
    gives it."""

    def __init__(self) -> None:
        self.served: dict[str, bytes] = {}

    def read(self, name: str, base: Path | None, key: str, what: str) -> bytes:
        """The file's bytes, read once (the parser and the builder both want the symbols)."""
        data = self.served.get(name)
        if data is None:
            data = self.served[name] = self._read(name, base, key, what)
        return data

    def _read(self, name: str, base: Path | None, key: str, what: str) -> bytes:
        raise NotImplementedError

    def output(self, name: str, base: Path | None, key: str) -> Path:
        raise NotImplementedError

    def fresh(self) -> FilePolicy:
        """The same policy with nothing served yet (one per configuration loaded)."""
        raise NotImplementedError


class Local(FilePolicy):
    """The operator's configuration (the command line, a test): any path, a relative one
    from the configuration's folder; read as `read_bounded` reads."""

    def _read(self, name: str, base: Path | None, key: str, what: str) -> bytes:
        return read_bounded(_anchor(name, base), key, what)

    def output(self, name: str, base: Path | None, key: str) -> Path:
        return _anchor(name, base)

    def fresh(self) -> Local:
        return Local()


def _anchor(name: str, base: Path | None) -> Path:
    path = Path(name)
    return base / path if base is not None and not path.is_absolute() else path


def carried_files(files: object) -> dict[str, bytes]:
    """A request's `files` ({name: text}) checked: at most MAX_CARRIED_FILES, names of at
    most MAX_NAME_LENGTH characters, each text within MAX_FILE_BYTES once encoded.
    ConfigError (code `value`) otherwise."""
    if files is None:
        return {}
    if not isinstance(files, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                              for k, v in files.items()):
        raise ConfigError(ConfigIssue("files", "expected a table of file name -> text",
                                      ConfigCode.TYPE))
    if len(files) > MAX_CARRIED_FILES:
        raise ConfigError(ConfigIssue("files", f"{len(files)} files: at most "
                                      f"{MAX_CARRIED_FILES}", ConfigCode.VALUE))
    out = {}
    for name, text in files.items():
        if not name or len(name) > MAX_NAME_LENGTH:
            raise ConfigError(ConfigIssue("files", f"a file name of 1 to {MAX_NAME_LENGTH} "
                                          f"characters", ConfigCode.VALUE))
        data = text.encode("utf-8", errors="surrogateescape")
        if len(data) > MAX_FILE_BYTES:
            raise ConfigError(ConfigIssue("files", f"{name!r}: over {MAX_FILE_BYTES} bytes",
                                          ConfigCode.VALUE))
        out[posixpath.normpath(name)] = data
    return out


class Carried(FilePolicy):
    """A configuration from the network: the files it carries (`files`: name -> bytes),
    then, if the operator named one (`root`), regular files under that folder; nothing
    else is read, and nothing is written."""

    def __init__(self, files: Mapping[str, bytes] | None = None, root: Path | None = None):
        super().__init__()
        self.files = dict(files or {})
        self.root = root

    def fresh(self) -> Carried:
        return Carried(self.files, self.root)

    @classmethod
    def holding(cls, files: Mapping[str, bytes]) -> Carried:
        """The policy of a configuration whose files were read already (`files`, served)."""
        policy = cls(files)
        policy.served.update(files)
        return policy

    def _read(self, name: str, base: Path | None, key: str, what: str) -> bytes:
        carried = self.files.get(posixpath.normpath(name))
        if carried is not None:
            return carried
        if self.root is None:
            raise _refused(key, f"{name!r}: a configuration received over the network names "
                                f"no file of the host; send the {what} with the request "
                                f"(`softplc load` does), or start the daemon with "
                                f"--config-dir DIR for files under DIR")
        return read_bounded(self._under_root(name, key), key, what, follow=False)

    def _under_root(self, name: str, key: str) -> Path:
        """`name` as a path under `root`: relative, no `..`, resolving (links included)
        inside `root`."""
        assert self.root is not None
        path = Path(name)
        if path.is_absolute() or ".." in path.parts or "\0" in name:
            raise _refused(key, f"{name!r}: a path relative to --config-dir, without '..'")
        root = self.root.resolve()
        full = (root / path).resolve()
        if not full.is_relative_to(root):
            raise _refused(key, f"{name!r} leads out of --config-dir (a symbolic link)")
        return full

    def output(self, name: str, base: Path | None, key: str) -> Path:
        raise _refused(key, f"{name!r}: a configuration received over the network writes "
                            f"no file")


__all__ = ["MAX_FILE_BYTES", "READ_DEADLINE_S", "Carried", "FilePolicy", "Local",
           "carried_files", "read_bounded"]
