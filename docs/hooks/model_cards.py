"""MkDocs hook: model pages include the model cards shipped in the package.

A line ``<!-- model-card: NAME -->`` in a page is replaced by
``src/emotive/assets/NAME/MODEL_CARD.md`` with every heading moved two levels down (the card's
title becomes a third-level heading under the page's "Model card" section). The card in the
package stays the one source.
"""

from __future__ import annotations

import re
from pathlib import Path

ASSETS = Path(__file__).resolve().parents[2] / "src" / "emotive" / "assets"
PATTERN = re.compile(r"^<!-- model-card: ([a-z0-9_-]+) -->$", re.MULTILINE)


def model_card(name: str) -> str:
    """The card of one asset folder, its headings two levels down."""
    text = (ASSETS / name / "MODEL_CARD.md").read_text()
    out, fenced = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        if not fenced and re.match(r"#{1,4} ", line):
            line = "##" + line
        out.append(line)
    return "\n".join(out) + "\n"


def on_page_markdown(markdown, page, config, files):
    return PATTERN.sub(lambda m: model_card(m.group(1)), markdown)


def on_config(config):
    # Rebuild when a card changes under `mkdocs serve`.
    config.setdefault("watch", []).append(str(ASSETS))
    return config
