"""mkdocs hooks (mkdocs.yml `hooks:`): the build fails when a generated reference page
differs from the code (`tools/gen_docs.py`); the design records of `docs/decisions/` are
listed by themselves (in the navigation and in the records' index page, from each record's
title and first sentence), so a new record needs no edit elsewhere; the architecture page
shows the import layers of `tools/check_structure.py` as they are; the site's changelog page
is the repository's CHANGELOG.md (one file, not a copy)."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import check_structure  # noqa: E402  (tools/ is not a package)
import gen_docs  # noqa: E402

CHANGELOG = "changelog.md"
DECISIONS = "decisions"
DECISIONS_TITLE = "Design decisions"
RECORDS_MARK = "<!-- records -->"  # where the index page gets its table of records
LAYERS_MARK = "<!-- layers -->"  # where the architecture page gets the import layers
# "**Decision.** ...", "**Decision:** ..." or a "## Decision" heading, then its sentence
DECISION = re.compile(r"(?:\*\*Decision[.:]?\*\*[.:]?|^#+ *Decision *[.:]? *$)\s+"
                      r"(?:\d+\.\s+|[-*]\s+)?(.+?\.)(?:\s|$)", re.S | re.M)
SUMMARY_MAX = 240  # characters of a decision's first sentence in the index's table


def records(docs: Path) -> list[Path]:
    """The design records, by file name (the index page apart)."""
    return sorted(p for p in (docs / DECISIONS).glob("*.md") if p.name != "index.md")


def _summary(text: str) -> tuple[str, str]:
    """A record's title and the first sentence of its decision."""
    title = re.search(r"^# (.+)$", text, re.M)
    decision = DECISION.search(text)
    sentence = " ".join(decision.group(1).split()) if decision else ""
    if len(sentence) > SUMMARY_MAX:  # a long one: up to its first colon, else cut short
        head = sentence.split(": ", 1)[0]
        sentence = head + ": ..." if len(head) <= SUMMARY_MAX \
            else sentence[:SUMMARY_MAX].rsplit(" ", 1)[0] + " ..."
    return (title.group(1).strip() if title else "", sentence)


def records_table(docs: Path) -> str:
    rows = ["| record | decision |", "|---|---|"]
    for p in records(docs):
        title, decision = _summary(p.read_text(encoding="utf-8"))
        rows.append(f"| [{title}]({p.name}) | {decision} |")
    return "\n".join(rows)


def on_config(config: Any) -> Any:
    docs = Path(config["docs_dir"])
    listed = [f"{DECISIONS}/index.md", *(f"{DECISIONS}/{p.name}" for p in records(docs))]
    for item in config["nav"] or []:
        if isinstance(item, dict) and DECISIONS_TITLE in item:
            item[DECISIONS_TITLE] = listed
    return config


def on_pre_build(config: Any) -> None:
    stale = gen_docs.stale(Path(config["docs_dir"]))
    if stale:
        raise PluginError("generated pages differ from the code: " + ", ".join(
            f"docs/{p}" for p in stale) + "; run .venv/bin/python tools/gen_docs.py")


def on_files(files: Files, config: Any) -> Files:
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    files.append(File.generated(config, CHANGELOG, content=text))
    return files


def layers_list() -> str:
    """The layers of tools/check_structure.py, lowest first, as a numbered list."""
    return "\n".join(f"{n}. " + ", ".join(f"`{m}`" for m in layer)
                     for n, layer in enumerate(check_structure.LAYERS, 1))


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    if page.file.src_uri == "architecture.md":
        if LAYERS_MARK not in markdown:
            raise PluginError(f"docs/architecture.md lost its {LAYERS_MARK} line")
        return markdown.replace(LAYERS_MARK, layers_list())
    if page.file.src_uri == f"{DECISIONS}/index.md":
        if RECORDS_MARK not in markdown:
            raise PluginError(f"docs/{DECISIONS}/index.md lost its {RECORDS_MARK} line")
        return markdown.replace(RECORDS_MARK, records_table(Path(config["docs_dir"])))
    return markdown
