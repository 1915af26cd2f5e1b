"""Build hooks of the documentation site (mkdocs.yml `hooks:`).

The home page is the README: `index.md` holds one line, and this hook puts the README in its place with its
links made relative to the docs folder, so the two never differ.
"""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def readme_as_home() -> str:
    """The README with links into docs/ made relative to docs/, and links to other repository files made
    public text (the site holds only docs/)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/", "](", text)
    return re.sub(r"\[([^\]]+)\]\((LICENSE)\)", r"`\2`", text)


def on_page_markdown(markdown: str, page, config, files) -> str:   # noqa: ARG001 (mkdocs' hook signature)
    """Replace the home page's placeholder with the README."""
    if page.file.src_uri == "index.md":
        return readme_as_home()
    return markdown
