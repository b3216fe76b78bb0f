"""The terminal front end of the debugger: `cmd` + readline over a `Session`.

Tab completes command names, then addresses the program uses (and rung titles after
`rung` / `break`); history is kept in ~/.softplc_history (or $SOFTPLC_HISTORY). Ctrl-C
stops a running `run` / `continue` at the next instruction or scan; Ctrl-D quits.
"""

from __future__ import annotations

import cmd
import os
import shutil
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from softplc.debug.session import Session

if TYPE_CHECKING:  # a plant's session is made by its command: a program's REPL starts
    # without the plant, the Modbus image and numpy
    from softplc.debug.plant_session import PlantSession

try:  # readline is missing on some platforms: the REPL then works without it
    import readline
except ImportError:  # pragma: no cover
    readline = None  # type: ignore[assignment]

PROMPT = "(softplc) "


class Repl(cmd.Cmd):
    prompt = PROMPT

    def __init__(self, session: Session | PlantSession, stdin: Any = None,
                 stdout: Any = None):
        super().__init__(stdin=stdin, stdout=stdout)
        self.session = session
        self._addresses: list[str] | None = None

    # cmd.Cmd hooks: every line goes to the session
    def onecmd(self, line: str) -> bool:
        if line == "EOF":
            line = "quit"
            self.stdout.write("\n")
        old = signal.signal(signal.SIGINT, lambda *_: self.session.interrupt())
        try:
            out = self.session.execute(line)
        except Exception as e:  # a bug must not end the session and lose its state
            out = f"internal error: {type(e).__name__}: {e}"
        finally:
            signal.signal(signal.SIGINT, old)
        if line.strip().split(" ")[0] == "reload":
            self._addresses = None
        if out:
            self.stdout.write(out.rstrip("\n") + "\n")
        return self.session.done

    def emptyline(self) -> bool:
        return False

    def completenames(self, text: str, *ignored: Any) -> list[str]:
        words = self.session.complete_words() + list(self.session.aliases)
        return sorted(w + " " for w in words if w.startswith(text))

    def completedefault(self, text: str, line: str, begidx: int, endidx: int) -> list[str]:
        if text.startswith("%"):
            if self._addresses is None:
                self._addresses = self.session.addresses()
            t = text.upper()
            return [a for a in self._addresses if a.upper().startswith(t)]
        first = line.split(" ")[0]
        if first in ("rung", "break", "b"):
            titles = [r.title for r in self.session.plc.ast.rungs if r.title]
            prefix = line[len(first) + 1:begidx]
            return [t[len(prefix):] for t in titles
                    if t.lower().startswith((prefix + text).lower())][:50]
        if first in ("help",):
            return self.completenames(text)
        return []

    def complete(self, text: str, state: int) -> str | None:
        # cmd.Cmd only completes with do_* methods; route everything through ours
        if state == 0:
            line = readline.get_line_buffer() if readline else ""
            begidx = readline.get_begidx() if readline else 0
            endidx = readline.get_endidx() if readline else 0
            if begidx > 0 and line[:begidx].strip():
                self.completion_matches = self.completedefault(text, line, begidx, endidx)
            else:
                self.completion_matches = self.completenames(text)
        try:
            return self.completion_matches[state]
        except IndexError:
            return None


def history_path() -> Path:
    return Path(os.environ.get("SOFTPLC_HISTORY") or Path.home() / ".softplc_history")


def run_repl(session: Session | PlantSession, intro: str = "",
             commands: list[str] | None = None) -> int:
    """Run commands given on the command line, then the interactive loop (unless one of
    them quit)."""
    repl = Repl(session)
    session.width = shutil.get_terminal_size().columns
    for c in commands or []:
        repl.stdout.write(PROMPT + c + "\n")
        if repl.onecmd(c):
            return 0
    hist = history_path()
    if readline is not None:
        readline.set_completer_delims(" \t\n")
        try:
            readline.read_history_file(hist)
        except OSError:
            pass
        readline.set_history_length(1000)
    try:
        while True:
            try:
                repl.cmdloop(intro)
                break
            except KeyboardInterrupt:  # at the prompt: a new prompt, not an exit
                sys.stdout.write("^C\n")
                intro = ""
    finally:
        session.close()
        if readline is not None:
            try:
                readline.write_history_file(hist)
            except OSError:
                pass
    return 0
