"""The state file's keeper thread: durable copies, and the file kept at its path.

`StateKeeper` runs beside the scan so that no disk write or check ever delays it:

- every `interval` seconds it flushes the retained state to disk (`StateStore.persist`);
- ten times a second it checks that the file at the `--state` path is still the one the
  daemon holds locked. Someone may delete it, move it away, or replace it with another
  file while the daemon runs; the daemon would then go on acknowledging writes into a file
  nobody will ever read, the next start would be a cold one, and a second daemon could
  start on the path. The keeper says so at once and re-creates the file from the mapped
  one (`StateStore.recreate`: every write acknowledged so far included), locked again. If
  that cannot be done (the folder is gone, another softplc took the path...), `on_change`
  tells the daemon, which stops acknowledging writes until the file is back (retried at
  each check).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from softplc.persist.retain import StateFileError, StateStore

log = logging.getLogger("softplc.retain")

CHECK_INTERVAL = 0.1  # seconds between two checks of the file's identity


class StateKeeper:
    """`store.persist()` every `interval` seconds (0: never here; the caller persists at the
    end) and the identity check every CHECK_INTERVAL, on one thread. `on_change(lost)` is
    called with why the state cannot be kept ("" when it can again); `say` reports."""

    def __init__(self, store: StateStore, interval: float,
                 on_change: Callable[[str], None] = lambda lost: None,
                 say: Callable[[str], None] = lambda text: None):
        self.store = store
        self.interval = interval
        self.on_change = on_change
        self.say = say
        self.error: OSError | None = None
        self.lost = ""  # why the file at the path is not kept ("": it is)
        self.recreated = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="state-keeper", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        ticks = 0
        every = max(1, round(self.interval / CHECK_INTERVAL)) if self.interval > 0 else 0
        while not self._stop.wait(CHECK_INTERVAL):
            self.check()
            ticks += 1
            if every and ticks % every == 0:
                self.persist()

    def persist(self) -> None:
        try:
            self.store.persist()
            self.error = None
        except OSError as e:
            self.error = e
            log.error("cannot flush state file %s: %s", self.store.path, e.strerror or e)

    def check(self) -> bool:
        """Is the file at the path the store's? If not, re-create it. True if it is kept."""
        what = self.store.check()
        if not what:
            return True
        where = f"state file {self.store.path}"
        try:
            self.store.recreate()
        except StateFileError as e:
            if not self.lost:  # loud once; retried at every check
                self.lost = f"{where} {what} and cannot be re-created ({e})"
                self.on_change(self.lost)  # refuse first: whoever reads the line sees it so
                log.error("%s: host writes are refused from now on", self.lost)
                self.say(f"ERROR: {self.lost}; host writes are refused until it can be")
            return False
        self.recreated += 1
        text = (f"{where} {what} while the daemon ran: re-created from memory with every "
                f"acknowledged write, locked again")
        if self.lost:
            self.lost = ""
            self.on_change("")
        log.error("%s", text)
        self.say(f"WARNING: {text}")
        return True

    def stop(self) -> None:
        """End the thread (the caller checks and persists a last time)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
