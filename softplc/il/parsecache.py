"""What parsing keeps between calls: programs parsed before, kept pickled, so that the same
text is parsed once; and, between processes, lark's analysed grammar (`grammar_file`).

The same program text is parsed again and again: a plant of identical controllers, an online
change compared with the running program, a REPL's reload, a test suite building a shipped
program hundreds of times. A program's syntax tree is mutable (dataclasses), so a cache
cannot hand out the one it parsed: it keeps the tree pickled and gives each caller its own
copy, which unpickles about 4 times faster than the text parses (the cutting table: 49 ->
11 ms). The pickles are this process's own, made from trees it parsed; nothing from outside
is ever unpickled.
"""

from __future__ import annotations

import os
import pickle
import sys
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")
# Programs kept (least recently used first out): a plant's few programs, a suite's dozens.
CACHE_ENTRIES = 32
# A longer text is parsed each time: the cache must not hold megabytes of source.
CACHE_MAX_CHARS = 256 * 1024

_kept: OrderedDict[Hashable, bytes] = OrderedDict()
_lock = threading.Lock()


def parsed(key: Hashable, text: str, parse: Callable[[], T]) -> T:
    """`parse()`, or a copy of what it returned before for the same `key` (which holds
    `text` and whatever else decides the result). A parse that raises keeps nothing."""
    if len(text) > CACHE_MAX_CHARS:
        return parse()
    with _lock:
        blob = _kept.get(key)
        if blob is not None:
            _kept.move_to_end(key)
    if blob is not None:
        return pickle.loads(blob)
    result = parse()
    blob = pickle.dumps(result, pickle.HIGHEST_PROTOCOL)
    with _lock:
        _kept[key] = blob
        while len(_kept) > CACHE_ENTRIES:
            _kept.popitem(last=False)
    return result


def grammar_file() -> str | bool:
    """Where lark keeps the analysed grammar (its LALR tables): building them costs about
    0.25 s in every process (each `softplc` command, each daemon start), loading them about
    0.02 s. Lark checks the grammar's hash in the file and rebuilds when it differs. In the
    user's cache directory rather than lark's default shared temp directory (the file is a
    pickle); False (no cache) when that directory cannot be written."""
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "softplc"
    try:
        base.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    if not os.access(base, os.W_OK):
        return False
    return str(base / f"il-grammar-py{sys.version_info[0]}{sys.version_info[1]}.lark")
