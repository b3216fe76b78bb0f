"""mkdocs hooks (mkdocs.yml `hooks:`): the build fails when a generated reference page
differs from the code (`tools/gen_docs.py`), and the site's changelog page is the
repository's CHANGELOG.md (one file, not a copy)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import gen_docs  # noqa: E402  (tools/ is not a package)

CHANGELOG = "changelog.md"


def on_pre_build(config: Any) -> None:
    stale = gen_docs.stale(Path(config["docs_dir"]))
    if stale:
        raise PluginError("generated pages differ from the code: " + ", ".join(
            f"docs/{p}" for p in stale) + "; run .venv/bin/python tools/gen_docs.py")


def on_files(files: Files, config: Any) -> Files:
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    files.append(File.generated(config, CHANGELOG, content=text))
    return files
